// Tests of common/mesh_io (loading and saving mesh files: formats, gzip, errors,
// warnings). In-memory geometry: test_mesh.cpp.
#include "common/error.h"
#include "common/mesh_io.h"
#include "common/shapes.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

namespace fs = std::filesystem;
using prt::TriangleMesh;

namespace {

class MeshFiles : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("prt-test-mesh-" + std::to_string(::getpid()) + "-" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    std::string file(const std::string& name) const { return (dir_ / name).string(); }
    std::string writeText(const std::string& name, const std::string& text) const {
        const std::string p = file(name);
        std::ofstream(p, std::ios::binary) << text;
        return p;
    }
    std::string readBytes(const std::string& p) const {
        std::ifstream in(p, std::ios::binary);
        std::ostringstream s;
        s << in.rdbuf();
        return s.str();
    }
    std::string gzipFile(const std::string& source, const std::string& name) const {
        const std::string bytes = readBytes(source);
        const std::string p = file(name);
        gzFile gz = gzopen(p.c_str(), "wb");
        EXPECT_NE(gz, nullptr);
        EXPECT_EQ(gzwrite(gz, bytes.data(), unsigned(bytes.size())), int(bytes.size()));
        EXPECT_EQ(gzclose(gz), Z_OK);
        return p;
    }
    // Number of files left in the system temp dir by loadMesh (must stay zero).
    // This process's decompression temporaries (other test processes run in parallel).
    static size_t leftoverTempFiles() {
        const std::string prefix = "prt-mesh-" + std::to_string(long(::getpid())) + "-";
        size_t n = 0;
        for (const auto& e : fs::directory_iterator(fs::temp_directory_path()))
            if (e.path().filename().string().rfind(prefix, 0) == 0) ++n;
        return n;
    }

    fs::path dir_;
};

// Expects fn to throw prt::Error whose what() names `path` and contains `text`.
void expectError(const std::function<void()>& fn, const std::string& path, const std::string& text) {
    try {
        fn();
        ADD_FAILURE() << "no prt::Error thrown (expected one mentioning '" << text << "')";
    } catch (const prt::Error& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find(path), std::string::npos) << what;
        EXPECT_NE(what.find(text), std::string::npos) << what;
        EXPECT_EQ(what.find('\n'), std::string::npos) << "error message should be one line: " << what;
    }
}

// Same triangles with the same corner positions (in order), whatever the vertex order.
void expectSameGeometry(const TriangleMesh& a, const TriangleMesh& b) {
    ASSERT_EQ(a.triangles.size(), b.triangles.size());
    for (size_t f = 0; f < a.triangles.size(); ++f)
        for (int k = 0; k < 3; ++k)
            ASSERT_EQ(a.positions[a.triangles[f][k]], b.positions[b.triangles[f][k]]) << "face " << f;
}

// Identical vertex order, positions and triangles.
void expectIdentical(const TriangleMesh& a, const TriangleMesh& b) {
    ASSERT_EQ(a.positions.size(), b.positions.size());
    for (size_t v = 0; v < a.positions.size(); ++v) ASSERT_EQ(a.positions[v], b.positions[v]) << v;
    ASSERT_EQ(a.triangles.size(), b.triangles.size());
    for (size_t f = 0; f < a.triangles.size(); ++f) ASSERT_EQ(a.triangles[f], b.triangles[f]) << f;
}

// Every loaded face is accounted for: kept or counted as removed.
void expectAccounted(const prt::MeshReport& r, const TriangleMesh& m) {
    EXPECT_EQ(r.triangles, m.triangles.size());
    EXPECT_EQ(r.vertices, m.positions.size());
    EXPECT_EQ(r.inputTriangles, m.triangles.size() + r.removedFaces);
}

const char* kTetraObj =
    "# tetrahedron, outward CCW\n"
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
    "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

}  // namespace

// ---------------------------------------------------------------------------------
// Save / load
// ---------------------------------------------------------------------------------

TEST_F(MeshFiles, RoundTripPlyObjOffKeepsEverything) {
    const TriangleMesh original = prt::makeIcosphere(2, 1.7f);
    for (const char* ext : {"ply", "obj", "off"}) {
        SCOPED_TRACE(ext);
        const std::string p = file(std::string("sphere.") + ext);
        prt::saveMesh(original, p);
        prt::MeshReport report;
        const TriangleMesh loaded = prt::loadMesh(p, &report);
        expectIdentical(original, loaded);
        EXPECT_EQ(report.format, ext);
        EXPECT_FALSE(report.compressed);
        EXPECT_EQ(report.fileVertices, original.positions.size());
        EXPECT_EQ(report.fileFaces, original.triangles.size());
        EXPECT_EQ(report.degenerateFaces, 0u);
        EXPECT_EQ(report.boundaryEdges, 0u);
        EXPECT_EQ(report.nonManifoldEdges, 0u);
        EXPECT_EQ(report.eulerCharacteristic, 2);
        expectAccounted(report, loaded);
        EXPECT_EQ(prt::meshFingerprint(loaded), prt::meshFingerprint(original));
        ASSERT_EQ(loaded.normals.size(), loaded.positions.size());
        for (size_t v = 0; v < loaded.positions.size(); ++v)
            EXPECT_GT(glm::dot(loaded.normals[v], loaded.positions[v]), 0.0f);
    }
}

TEST_F(MeshFiles, RoundTripStlMergesIdenticalCorners) {
    // STL stores corners per triangle; OpenMesh's reader merges identical positions.
    const TriangleMesh sphere = prt::makeIcosphere(2, 1.0f);
    prt::saveMesh(sphere, file("sphere.stl"));
    prt::MeshReport report;
    const TriangleMesh s = prt::loadMesh(file("sphere.stl"), &report);
    EXPECT_EQ(s.positions.size(), sphere.positions.size());
    expectSameGeometry(sphere, s);
    EXPECT_EQ(report.boundaryEdges, 0u);
    EXPECT_EQ(analyseTopology(s, false).boundaryEdges, 0u);  // really shared, not just welded

    const TriangleMesh box = prt::makeBox(glm::vec3(1, 2, 3));
    prt::saveMesh(box, file("box.stl"));
    const TriangleMesh b = prt::loadMesh(file("box.stl"));
    EXPECT_EQ(b.positions.size(), 8u);  // 24 split vertices merged into 8 corners
    EXPECT_EQ(b.triangles.size(), 12u);
    expectSameGeometry(box, b);
    EXPECT_NEAR(prt::signedVolume(b), 6.0, 1e-5);
}

TEST_F(MeshFiles, AsciiStl) {
    const std::string p = writeText("tri.stl",
                                    "solid t\n"
                                    " facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n"
                                    "   vertex 0 1 0\n  endloop\n endfacet\n"
                                    " facet normal 0 0 1\n  outer loop\n   vertex 1 0 0\n   vertex 1 1 0\n"
                                    "   vertex 0 1 0\n  endloop\n endfacet\n"
                                    "endsolid t\n");
    prt::MeshReport report;
    const TriangleMesh m = prt::loadMesh(p, &report);
    EXPECT_EQ(m.positions.size(), 4u);
    EXPECT_EQ(m.triangles.size(), 2u);
    EXPECT_NEAR(prt::totalArea(m), 1.0, 1e-6);
    EXPECT_EQ(report.boundaryEdges, 4u);
}

TEST_F(MeshFiles, GzipCompressedFiles) {
    const TriangleMesh original = prt::makeTorus(2.0f, 0.5f, 16, 8);
    for (const char* ext : {"ply", "obj", "off", "stl"}) {
        SCOPED_TRACE(ext);
        const std::string plain = file(std::string("torus.") + ext);
        prt::saveMesh(original, plain);
        const std::string gz = gzipFile(plain, std::string("torus.") + ext + ".gz");
        prt::MeshReport report;
        const TriangleMesh loaded = prt::loadMesh(gz, &report);
        EXPECT_TRUE(report.compressed);
        EXPECT_EQ(report.format, ext);
        if (std::string(ext) == "stl")
            expectSameGeometry(original, loaded);
        else
            expectIdentical(original, loaded);
        EXPECT_EQ(prt::meshFingerprint(loaded), prt::meshFingerprint(prt::loadMesh(plain)));
    }
    EXPECT_EQ(leftoverTempFiles(), 0u);
}

TEST_F(MeshFiles, CorruptGzipIsAnError) {
    prt::saveMesh(prt::makeIcosphere(3, 1.0f), file("s.ply"));
    const std::string gz = gzipFile(file("s.ply"), "s.ply.gz");
    std::string bytes = readBytes(gz);
    bytes.resize(bytes.size() / 2);
    const std::string cut = writeText("cut.ply.gz", bytes);
    expectError([&] { prt::loadMesh(cut); }, cut, "truncated");
    EXPECT_EQ(leftoverTempFiles(), 0u);
}

TEST_F(MeshFiles, LoadIsDeterministic) {
    prt::saveMesh(prt::makeTorus(3.0f, 1.0f, 40, 20), file("t.ply"));
    const uint64_t first = prt::meshFingerprint(prt::loadMesh(file("t.ply")));
    for (int i = 0; i < 3; ++i) EXPECT_EQ(prt::meshFingerprint(prt::loadMesh(file("t.ply"))), first);
}

TEST_F(MeshFiles, SaveReplacesAtomicallyAndRejectsUnknownFormats) {
    const std::string p = file("m.obj");
    prt::saveMesh(prt::makeIcosphere(0, 1.0f), p);
    prt::saveMesh(prt::makeIcosphere(1, 1.0f), p);
    EXPECT_EQ(prt::loadMesh(p).positions.size(), 42u);
    size_t entries = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++entries;
    EXPECT_EQ(entries, 1u);  // no temporary left behind
    expectError([&] { prt::saveMesh(prt::makeIcosphere(0, 1.0f), file("m.xyz")); }, file("m.xyz"), "extension");
    expectError([&] { prt::saveMesh(prt::makeIcosphere(0, 1.0f), file("m.ply.gz")); }, file("m.ply.gz"),
                "not supported");
    expectError([&] { prt::saveMesh(prt::makeIcosphere(0, 1.0f), file("no/such/dir/m.ply")); },
                file("no/such/dir/m.ply"), "");
}

TEST_F(MeshFiles, QuadsAndPolygonsAreTriangulated) {
    // Unit cube of quads, outward.
    const std::string cube = writeText("cube.obj",
                                       "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                                       "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
    prt::MeshReport report;
    const TriangleMesh m = prt::loadMesh(cube, &report);
    EXPECT_EQ(m.triangles.size(), 12u);
    EXPECT_EQ(report.polygonsTriangulated, 6u);
    EXPECT_EQ(report.fileFaces, 6u);
    EXPECT_NEAR(prt::totalArea(m), 6.0, 1e-6);
    EXPECT_NEAR(prt::signedVolume(m), 1.0, 1e-6);
    EXPECT_EQ(report.boundaryEdges, 0u);
    EXPECT_EQ(report.inconsistentEdges, 0u);
    expectAccounted(report, m);

    // A non-convex L-shaped hexagon (area 3): a fan from vertex 1 would cover the notch.
    const std::string ell = writeText("ell.off",
                                      "OFF\n6 1 0\n2 1 0\n1 1 0\n1 2 0\n0 2 0\n0 0 0\n2 0 0\n6 0 1 2 3 4 5\n");
    const TriangleMesh l = prt::loadMesh(ell);
    EXPECT_EQ(l.triangles.size(), 4u);
    EXPECT_NEAR(prt::totalArea(l), 3.0, 1e-6);
    for (size_t f = 0; f < l.triangles.size(); ++f) EXPECT_GT(prt::faceNormal(l, f).z, 0.99f);
}

TEST_F(MeshFiles, AsciiAndBinaryPly) {
    const std::string ascii = writeText("a.ply",
                                        "ply\nformat ascii 1.0\ncomment test\nelement vertex 4\n"
                                        "property float x\nproperty float y\nproperty float z\n"
                                        "property float confidence\n"
                                        "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
                                        "0 0 0 1\n1 0 0 1\n0 1 0 1\n0 0 1 1\n"
                                        "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n");
    prt::MeshReport report;
    const TriangleMesh a = prt::loadMesh(ascii, &report);
    EXPECT_EQ(a.positions.size(), 4u);
    EXPECT_EQ(a.triangles.size(), 4u);
    EXPECT_NEAR(prt::signedVolume(a), 1.0 / 6.0, 1e-7);
    EXPECT_EQ(report.boundaryEdges, 0u);
    // Binary through saveMesh, compared with the OBJ version of the same text.
    prt::saveMesh(a, file("b.ply"));
    EXPECT_NE(readBytes(file("b.ply")).find("binary_little_endian"), std::string::npos);
    expectIdentical(a, prt::loadMesh(file("b.ply")));
    expectIdentical(a, prt::loadMesh(writeText("t.obj", kTetraObj)));
}

// ---------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------

TEST_F(MeshFiles, MissingFileAndUnknownExtension) {
    const std::string missing = file("nope.ply");
    expectError([&] { prt::loadMesh(missing); }, missing, "no such file");
    const std::string odd = writeText("mesh.xyz", kTetraObj);
    expectError([&] { prt::loadMesh(odd); }, odd, "extension");
    const std::string none = writeText("mesh", kTetraObj);
    expectError([&] { prt::loadMesh(none); }, none, "extension");
}

TEST_F(MeshFiles, GarbageFiles) {
    const std::string text = "this is not a mesh\n\x01\x02\x03 at all\n";
    for (const char* name : {"g.ply", "g.obj", "g.off", "g.stl"}) {
        SCOPED_TRACE(name);
        const std::string p = writeText(name, text);
        expectError([&] { prt::loadMesh(p); }, p, "");
    }
    const std::string empty = writeText("e.obj", "");
    expectError([&] { prt::loadMesh(empty); }, empty, "empty");
    // A PLY header that promises more than the body has.
    const std::string shortPly = writeText("short.ply",
                                           "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n"
                                           "property float y\nproperty float z\nelement face 1\n"
                                           "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n");
    expectError([&] { prt::loadMesh(shortPly); }, shortPly, "truncated");
    // A binary PLY cut short.
    prt::saveMesh(prt::makeIcosphere(2, 1.0f), file("full.ply"));
    std::string bytes = readBytes(file("full.ply"));
    bytes.resize(bytes.size() - 100);
    const std::string cut = writeText("cut.ply", bytes);
    expectError([&] { prt::loadMesh(cut); }, cut, "truncated");
}

// Inputs the fuzzer found (tools/fuzz/crashes/mesh/): OpenMesh 9.0 loops forever on a
// malformed PLY header and appends corners until memory runs out when a face's corner
// count exceeds the file; both are refused before OpenMesh reads the file.
TEST_F(MeshFiles, MalformedHeadersAndCountsAreRefusedBeforeOpenMesh) {
    const std::string tail = "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    const std::string vertexProps = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    const std::string faceProps = "element face 1\nproperty list uchar int vertex_indices\n";
    const std::string badFormat = writeText("format.ply", "ply\nformat ascii nt vertex_indices\n" + tail);
    expectError([&] { prt::loadMesh(badFormat); }, badFormat, "malformed format line");
    const std::string badKeyword =
        writeText("keyword.ply", "ply\nformat ascii 1.0\n" + vertexProps + "elephant 3\n" + faceProps + tail);
    expectError([&] { prt::loadMesh(badKeyword); }, badKeyword, "unknown header keyword 'elephant'");
    const std::string badType = writeText(
        "type.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty real x\nproperty float y\n"
                    "property float z\n" + faceProps + tail);
    expectError([&] { prt::loadMesh(badType); }, badType, "unknown property type 'real'");
    const std::string huge = writeText(
        "huge.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
                    "property float y\nproperty float z\n" + faceProps + "end_header\n0000");
    expectError([&] { prt::loadMesh(huge); }, huge, "declares 4000000000 vertex records");
    const std::string longList = writeText(
        "list.ply", "ply\nformat ascii 1.0\n" + vertexProps + faceProps + "end_header\n0 0 0\n1 0 0\n0 1 0\n200 0 1 2\n");
    expectError([&] { prt::loadMesh(longList); }, longList, "file ends inside face 0");
    const std::string offCorners = writeText("corners.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3000000000 0 1 2\n");
    expectError([&] { prt::loadMesh(offCorners); }, offCorners, "declares 3000000000 corners");
    const std::string offText = writeText("count.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\nthree 0 1 2\n");
    expectError([&] { prt::loadMesh(offText); }, offText, "corner count 'three'");
    // A face index OpenMesh's stream cannot read, and a vertex split over two lines: its
    // reader looped forever on both (tools/fuzz/crashes/mesh/openmesh-off-bad-index-loop).
    const std::string offIndex = writeText("index.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1p 2\n");
    expectError([&] { prt::loadMesh(offIndex); }, offIndex, "line 6: cannot parse vertex index '1p' of face 0");
    const std::string offSplit = writeText("split.off", "OFF\n3 1 0\n0 0\n0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(offSplit); }, offSplit, "line 3: vertex 0 has 2 coordinates");
    const std::string offEmptyFace = writeText("empty_face.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n0 1.5 2 3\n");
    expectError([&] { prt::loadMesh(offEmptyFace); }, offEmptyFace, "line 6: face 0 has 0 corners (a face needs at least 3)");
    // A fourth number after the counts shifted OpenMesh's reading of every record after
    // it; a face then had 2^32 - 8 corners (tools/fuzz/crashes/mesh/openmesh-off-counts-line-extra-token-oom).
    const std::string offExtra = writeText("extra.off", "OFF\n3 1 0 -8.5\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(offExtra); }, offExtra, "line 2: more than the vertex, face and edge counts");
    const std::string offSplitCounts = writeText("split_counts.off", "OFF\n3 1\n0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(offSplitCounts); }, offSplitCounts, "counts must be on one line");
    // The same on a vertex line (tools/fuzz/crashes/mesh/openmesh-off-vertex-extra-value-oom).
    const std::string offVertexExtra = writeText("vertex_extra.off", "OFF\n3 1 0\n0 0 0 -8.5\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(offVertexExtra); }, offVertexExtra, "line 3: vertex 0 has 4 values, expected x y z only");
    const std::string offTrailingSpace = writeText("trailing.off", "OFF\n3 1 0  \r\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(prt::loadMesh(offTrailingSpace).triangleCount(), 1u);
    const std::string offVariant = writeText("variant.off", "COFF\n3 1 0\n0 0 0 1 1 1 1\n1 0 0 1 1 1 1\n0 1 0 1 1 1 1\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(offVariant); }, offVariant, "unsupported OFF header 'COFF'");
    const std::string offRange = writeText("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
    expectError([&] { prt::loadMesh(offRange); }, offRange, "line 6: face 0 refers to vertex 7 but the file has 3 vertices");
    // Blank lines between records and colours after a face are fine; a comment is
    // refused (OpenMesh reads it as numbers).
    EXPECT_EQ(prt::loadMesh(writeText("gaps.off", "OFF\n3 1 0\n\n0 0 0\n1 0 0\n0 1 0\n\n3 0 1 2 255 0 0\n"))
                  .triangleCount(), 1u);
    const std::string offComment = writeText("comment.off", "OFF\n3 1 0\n0 0 0\n# c\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(offComment); }, offComment, "line 4: vertex 1 has 2 coordinates");
    const std::string tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n";
    for (const char* face : {"f /1 /2 /3", "f", "f 1 2 x", "f 0 2 4", "f 1//", "f 1/2/3/4 2 3", "f 1 f 3"}) {
        SCOPED_TRACE(face);
        const std::string obj = writeText("face.obj", tetra + face + "\n");
        expectError([&] { prt::loadMesh(obj); }, obj, "line 8");
    }
    EXPECT_EQ(prt::loadMesh(writeText("corners.obj", tetra + "f 1/1 -1//2 3/4/5\n")).triangleCount(), 4u);
    // The well-formed versions load.
    EXPECT_EQ(prt::loadMesh(writeText("ok.ply", "ply\nformat ascii 1.0\ncomment fine\n" + vertexProps + faceProps + tail))
                  .triangleCount(), 1u);
    EXPECT_EQ(prt::loadMesh(writeText("ok.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")).triangleCount(), 1u);
}

TEST_F(MeshFiles, EmptyMeshes) {
    const std::string points = writeText("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    expectError([&] { prt::loadMesh(points); }, points, "no faces");
    const std::string comments = writeText("comments.obj", "# nothing here\n");
    expectError([&] { prt::loadMesh(comments); }, comments, "no faces");
    const std::string off = writeText("empty.off", "OFF\n0 0 0\n");
    expectError([&] { prt::loadMesh(off); }, off, "no faces");
}

TEST_F(MeshFiles, NonFiniteCoordinates) {
    const std::string obj = writeText("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    expectError([&] { prt::loadMesh(obj); }, obj, "non-finite");
    const std::string inf = writeText("inf.obj", "v 0 0 0\nv 1 inf 0\nv 0 1 0\nf 1 2 3\n");
    expectError([&] { prt::loadMesh(inf); }, inf, "line 2");
    const std::string big = writeText("big.obj", "v 0 0 0\nv 1 1e999 0\nv 0 1 0\nf 1 2 3\n");
    expectError([&] { prt::loadMesh(big); }, big, "overflows");
    const std::string off = writeText("nan.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 NaN 0\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(off); }, off, "non-finite");
    const std::string ply = writeText("nan.ply",
                                      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                      "property float y\nproperty float z\nelement face 1\n"
                                      "property list uchar int vertex_indices\nend_header\n"
                                      "0 0 0\n1 -inf 0\n0 1 0\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(ply); }, ply, "non-finite");
    const std::string stl = writeText("nan.stl",
                                      "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex nan 0 0\n"
                                      "vertex 0 1 0\nendloop\nendfacet\nendsolid t\n");
    expectError([&] { prt::loadMesh(stl); }, stl, "non-finite");
    // Binary: the NaN reaches the loaded positions.
    TriangleMesh m = prt::makeIcosphere(1, 1.0f);
    m.positions[7].y = std::nanf("");
    prt::saveMesh(m, file("nan-bin.ply"));
    expectError([&] { prt::loadMesh(file("nan-bin.ply")); }, file("nan-bin.ply"), "vertex 7");
    m.positions[7].y = std::numeric_limits<float>::infinity();
    prt::saveMesh(m, file("inf-bin.stl"));
    expectError([&] { prt::loadMesh(file("inf-bin.stl")); }, file("inf-bin.stl"), "non-finite");
}

TEST_F(MeshFiles, AllDegenerate) {
    const std::string line = writeText("line.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n");
    expectError([&] { prt::loadMesh(line); }, line, "degenerate");
    const std::string point = writeText("point.ply",
                                        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                        "property float y\nproperty float z\nelement face 1\n"
                                        "property list uchar int vertex_indices\nend_header\n"
                                        "1 1 1\n1 1 1\n1 1 1\n3 0 1 2\n");
    expectError([&] { prt::loadMesh(point); }, point, "degenerate");
}

TEST_F(MeshFiles, FaceIndexOutOfRange) {
    const std::string obj = writeText("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    expectError([&] { prt::loadMesh(obj); }, obj, "refers to vertex");
    const std::string off = writeText("bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
    expectError([&] { prt::loadMesh(off); }, off, "refers to vertex");
}

// ---------------------------------------------------------------------------------
// Warnings that are survived
// ---------------------------------------------------------------------------------

TEST_F(MeshFiles, DegenerateFacesDroppedAndReported) {
    const std::string p = writeText("deg.obj",
                                    std::string(kTetraObj) +
                                        "v 0.5 0 0\n"   // 5: on edge 1-2
                                        "f 1 2 5\n"     // zero area (collinear)
                                        "f 1 1 2\n"     // repeated corner (OpenMesh drops it itself)
                                        "f 3 4 4 3\n");  // polygon with only two distinct corners
    prt::MeshReport report;
    const TriangleMesh m = prt::loadMesh(p, &report);
    EXPECT_EQ(m.triangles.size(), 4u);
    EXPECT_EQ(report.degenerateFaces, 3u);
    EXPECT_EQ(report.removedFaces, 3u);
    EXPECT_EQ(report.fileFaces, 7u);
    EXPECT_EQ(report.unreferencedVertices, 1u);  // vertex 5 only served the dropped face
    EXPECT_EQ(m.positions.size(), 4u);
    EXPECT_EQ(report.boundaryEdges, 0u);
    expectAccounted(report, m);
    EXPECT_NEAR(prt::signedVolume(m), 1.0 / 6.0, 1e-7);
}

TEST_F(MeshFiles, NonManifoldEdgeSurvives) {
    // Three triangles share the edge 1-2 (a "fin"); OpenMesh's own mesh would refuse
    // the third ("complex edge"), the loader keeps all three.
    const std::string p = writeText("fin.obj",
                                    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\n"
                                    "f 1 2 3\nf 2 1 4\nf 1 2 5\n");
    prt::MeshReport report;
    const TriangleMesh m = prt::loadMesh(p, &report);
    EXPECT_EQ(m.triangles.size(), 3u);
    EXPECT_EQ(m.positions.size(), 5u);
    EXPECT_EQ(report.nonManifoldEdges, 1u);
    EXPECT_EQ(report.boundaryEdges, 6u);
    EXPECT_EQ(report.degenerateFaces, 0u);
    expectAccounted(report, m);
    // saveMesh writes non-manifold meshes unchanged too.
    prt::saveMesh(m, file("fin.ply"));
    expectIdentical(m, prt::loadMesh(file("fin.ply")));
}

TEST_F(MeshFiles, OpenAndMisorientedMeshesSurvive) {
    prt::MeshReport report;
    const TriangleMesh quad = prt::loadMesh(writeText("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"),
                                            &report);
    EXPECT_EQ(quad.triangles.size(), 2u);
    EXPECT_EQ(report.boundaryEdges, 4u);
    EXPECT_EQ(report.eulerCharacteristic, 1);

    const std::string flipped = writeText("flip.obj",
                                          "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
                                          "f 1 2 3\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    const TriangleMesh f = prt::loadMesh(flipped, &report);
    EXPECT_EQ(f.triangles.size(), 4u);
    EXPECT_EQ(report.inconsistentEdges, 3u);
}

TEST_F(MeshFiles, UnreferencedVerticesRemovedInOrder) {
    const std::string p = writeText("extra.obj",
                                    "v 9 9 9\nv 0 0 0\nv 1 0 0\nv 8 8 8\nv 0 1 0\nv 0 0 1\nv 7 7 7\n"
                                    "f 2 5 3\nf 2 3 6\nf 2 6 5\nf 3 5 6\n");
    prt::MeshReport report;
    const TriangleMesh m = prt::loadMesh(p, &report);
    EXPECT_EQ(report.unreferencedVertices, 3u);
    EXPECT_EQ(report.fileVertices, 7u);
    const std::vector<glm::vec3> expected{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    EXPECT_EQ(m.positions, expected);
    EXPECT_EQ(m.triangles[0], glm::uvec3(0, 2, 1));
}

// ---------------------------------------------------------------------------------
// loadMeshSurface: the same mesh, plus what the file says about the surface
// ---------------------------------------------------------------------------------

TEST_F(MeshFiles, SurfaceMeshIsLoadMeshsMesh) {
    const TriangleMesh original = prt::makeIcosphere(2, 1.3f);
    for (const char* ext : {"ply", "obj", "off", "stl"}) {
        SCOPED_TRACE(ext);
        const std::string p = file(std::string("s.") + ext);
        prt::saveMesh(original, p);
        prt::MeshSurface surface;
        prt::MeshReport a, b;
        const TriangleMesh plain = prt::loadMesh(p, &a);
        const TriangleMesh withSurface = prt::loadMeshSurface(p, surface, &b);
        expectIdentical(plain, withSurface);
        EXPECT_EQ(prt::meshFingerprint(plain), prt::meshFingerprint(withSurface));
        EXPECT_EQ(a.vertices, b.vertices);
        EXPECT_TRUE(surface.uvs.empty());  // saveMesh writes no texture coordinates
        EXPECT_EQ(surface.triangleMaterials.size(), plain.triangles.size());
        ASSERT_FALSE(surface.materials.empty());
    }
}

TEST_F(MeshFiles, SurfaceFollowsTriangulationAndDroppedFaces) {
    // The L-shaped hexagon (ear clipping, not a fan) with one vt per corner, u = 10 x + y,
    // v = vertex number; a quad; a degenerate triangle (zero area) between them.
    const std::string obj = writeText("ell.obj",
                                      "v 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\nv 2 0 0\nv 3 0 0\nv 4 0 0\n"
                                      "vt 21 1\nvt 11 2\nvt 12 3\nvt 2 4\nvt 0 5\nvt 20 6\nvt 30 7\nvt 40 8\n"
                                      "vn 0 0 1\nvn 0 0 -1\n"
                                      "f 1/1/1 2/2/1 3/3/1 4/4/1 5/5/1 6/6/1\n"
                                      "f 6/6/2 7/7/2 8/8/2\n"
                                      "f 6/6 7/7 1/1 2/2\n");
    prt::MeshSurface surface;
    prt::MeshReport report;
    const TriangleMesh m = prt::loadMeshSurface(obj, surface, &report);
    EXPECT_EQ(prt::meshFingerprint(m), prt::meshFingerprint(prt::loadMesh(obj)));
    EXPECT_EQ(report.degenerateFaces, 1u);
    ASSERT_EQ(m.triangles.size(), 6u);  // 4 from the hexagon, 2 from the quad
    ASSERT_EQ(surface.uvs.size(), 18u);
    ASSERT_EQ(surface.normals.size(), 18u);
    for (size_t t = 0; t < m.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const glm::vec3 p = m.positions[m.triangles[t][k]];
            const glm::vec2 uv = surface.uvs[t * 3 + size_t(k)];
            EXPECT_EQ(uv.x, 10.0f * p.x + p.y) << "triangle " << t << " corner " << k;
            if (t < 4) EXPECT_EQ(surface.normals[t * 3 + size_t(k)], glm::vec3(0, 0, 1));
            else EXPECT_TRUE(std::isnan(surface.normals[t * 3 + size_t(k)].x));  // the quad has no vn
        }
    // No usemtl: every triangle has the default material.
    ASSERT_EQ(surface.materials.size(), 1u);
    for (uint32_t mat : surface.triangleMaterials) EXPECT_EQ(mat, 0u);
}

TEST_F(MeshFiles, GltfIsInTheExtensionMessage) {
    const std::string odd = writeText("mesh.xyz", kTetraObj);
    expectError([&] { prt::loadMesh(odd); }, odd, ".gltf .glb");
    const std::string gz = writeText("mesh.glb.gz", "x");
    expectError([&] { prt::loadMesh(gz); }, gz, "compressed glTF");
}
