#pragma once
// The transport file: what prt-precompute writes and the renderer, viewer and
// reference tools read (SPEC sections 5-6, byte layout in docs/transport-format.md).
//
// In memory a transport file is a few components (multiple scattering, isotropic
// single scattering, the K terms of the SVD-factored single-scattering phase, the
// per-profile transport of editable multiple scattering), each one sparse RGB vector
// per mesh vertex in Haar coefficient space (common/haar.h: coefficient index
// face * N * N + j * N + i of a 6 x N x N cubemap), plus the h_k view maps when K-term
// components exist, the radial basis when profile components exist, the parameters
// the file was made with and a fingerprint of the mesh it belongs to.
//
// Relighting a vertex v of a component against a Haar light vector L (RGB):
//     out_c = scales[3v + c] * sum_{n = offsets[v]}^{offsets[v+1]-1}
//                                  values[3n + c] * L[indices[n]].c
// so the kernel streams offsets / indices / values once and multiplies by the
// per-vertex scale at the end.
//
// Every failure (missing, truncated, corrupt, foreign or mismatched file; invalid
// data handed to saveTransportFile) is a prt::Error(path, one-line reason).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/blocked_vectors.h"
#include "common/radial_basis.h"

namespace prt {

// Identifies the mesh a transport file was computed for: its vertex count and a hash
// of its vertex positions in file units (computed by the mesh module; this module
// only stores and compares it).
struct MeshFingerprint {
    uint64_t vertexCount = 0;
    uint64_t positionHash = 0;
    bool operator==(const MeshFingerprint&) const = default;
};

enum class ComponentKind : uint32_t {
    MultipleScattering = 1,
    SingleScatteringIsotropic = 2,
    SingleScatteringTerm = 3,  // k-th term of the SVD-factored phase; term index stored
    // Editable multiple scattering (format version 5): the transport vectors U_j of the
    // file's radial basis profiles B_j (TransportFile::radialBasis), packed three per
    // component: term p holds profiles 3p, 3p+1, 3p+2 in its channels R, G, B. The
    // relit multiple scattering of channel c is sum_j w_cj U_j with w_c =
    // RadialBasis::materialWeights (see common/radial_basis.h). The P components of a
    // file are terms 0..P-1, all per vertex or all blocked. Per vertex they share one
    // index list (equal `offsets` and `indices`), so a relight walks the indices once
    // for all J; blocked they share one block order and keep nested lists of their own
    // per block (format version 7; blocked_vectors.h, jointTruncateNested), or one list
    // for all (version 5).
    MultipleScatteringProfiles = 4,
};

// The profiles component term p packs, 3p .. 3p + 2 (kProfilesPerComponent of them).
inline constexpr uint32_t kProfilesPerComponent = 3;

// "multiple scattering", "single scattering (isotropic)", "single scattering term 2",
// "multiple scattering profiles 3-5" (kind 4, term 1).
std::string componentName(ComponentKind kind, uint32_t term = 0);

// One sparse RGB vector per vertex, CSR layout, 16-bit quantized.
//
// QUANTIZATION. Each vertex has one scale per channel, scale = max_n |v_nc| / 32767
// (stored as float); a value is stored as q = round(v / scale), an int16 in
// [-32767, 32767], and reads back as q * scale. A channel that is zero for the whole
// vertex has scale 0 (and q = 0). The worst-case error of a value is half a step,
//     |v - q * scale| <= 0.5 * scale = max_n |v_nc| / 65534   (relative to the
// vertex's per-channel maximum), plus float rounding of the scale and the product,
// less than 2^-23 * max_n |v_nc|: kQuantizationMaxRelativeError below. (A channel
// whose maximum is below 32767 * FLT_MIN ~ 3.9e-34 is stored as zero, scale 0.)
//
// EIGHT-BIT HAAR VALUES (haarBits = 8; the radial-profile components of an editable
// file, which keep more terms in fewer bytes): the indices below shFrom (the
// Haar terms) hold q in [-127, 127] with scale = max over those indices / 127, so their
// error is at most max / 254 (kEightBitHaarMaxRelativeError); the indices from shFrom
// on (the SH part, transport_file.h's shIndexBegin) keep 16 bits with a scale of their
// own, shScales[3v + c] = max over them / 32767. WHY: the SH band-0 term dwarfs the
// Haar ones, and one 8-bit scale set by it would leave the Haar terms a few levels.
// shFrom = UINT32_MAX (no SH part): every index is a Haar index and shScales is empty.
// haarBits = 16 (the default): shFrom = UINT32_MAX and shScales empty, as above.
struct SparseRgbVectors {
    std::vector<uint32_t> offsets{0};  // V + 1; vertex v owns [offsets[v], offsets[v+1])
    std::vector<uint16_t> indices;     // strictly increasing within a vertex, < 6 N^2 + shTerms
    std::vector<int16_t> values;       // 3 per coefficient, RGB interleaved
    std::vector<float> scales;         // 3 per vertex: value = q * scales[3v + c] (index < shFrom)
    uint32_t haarBits = 16;            // 16, or 8 (EIGHT-BIT HAAR VALUES)
    uint32_t shFrom = UINT32_MAX;      // with haarBits 8: the first index scaled by shScales
    std::vector<float> shScales;       // 3 per vertex iff haarBits 8 and shFrom set

    // Switches an empty vector set to EIGHT-BIT HAAR VALUES, the SH part (if any, else
    // UINT32_MAX) from shIndex on. Throws prt::Error when vertices were appended.
    void useEightBitHaar(uint32_t shIndex);
    // The scale of coefficient n (of vertex v), channel c.
    float scaleOf(size_t v, size_t n, int c) const {
        return indices[n] < shFrom ? scales[3 * v + size_t(c)] : shScales[3 * v + size_t(c)];
    }

    size_t vertexCount() const { return offsets.empty() ? 0 : offsets.size() - 1; }
    size_t coefficientCount() const { return indices.size(); }

    // Appends the next vertex: coefficient indices idx (any order, no duplicates,
    // each < 65536) and their RGB values rgb (3 per index, finite). Indices are
    // sorted. Throws prt::Error on a size mismatch, duplicate index, non-finite value
    // or more than 2^32 - 1 coefficients in total. Coefficients are never dropped,
    // even when they quantize to zero.
    void appendVertex(std::span<const uint32_t> idx, std::span<const float> rgb);

    // Vertex v's indices and dequantized RGB values (3 per index), replacing the
    // contents of idx and rgb. Throws std::out_of_range if v >= vertexCount().
    void dequantizeVertex(size_t v, std::vector<uint32_t>& idx, std::vector<float>& rgb) const;

    void reserve(size_t vertices, size_t coefficients);
    void clear();  // back to zero vertices

    // Bytes of the four arrays in memory (what a relight pass streams).
    size_t byteSize() const;

    bool operator==(const SparseRgbVectors&) const = default;
};

// Bound of |v - dequantized v| / max_n |v_nc| (see SparseRgbVectors).
inline constexpr double kQuantizationMaxRelativeError = 0.5 / 32767.0 + 1.0 / 8388608.0;
// The same bound for the Haar terms of haarBits = 8 vectors, relative to the maximum over
// the vertex's Haar terms in that channel (its SH terms keep kQuantizationMaxRelativeError
// relative to theirs).
inline constexpr double kEightBitHaarMaxRelativeError = 0.5 / 127.0 + 1.0 / 8388608.0;

// A component holds its vectors in one of two encodings: per vertex (`vectors`, the
// default) or in blocks of 16 vertices sharing their indices (`blocks`,
// common/blocked_vectors.h; prt-precompute --block-coefficients). A blocked component
// has blocks.vertices > 0 and empty `vectors`.
struct TransportComponent {
    ComponentKind kind = ComponentKind::MultipleScattering;
    uint32_t term = 0;  // 0 unless SingleScatteringTerm
    SparseRgbVectors vectors;
    BlockedRgbVectors blocks;

    bool blocked() const { return blocks.vertices > 0; }
    size_t vertexCount() const { return blocked() ? blocks.vertexCount() : vectors.vertexCount(); }
    // Vertex v's indices and dequantized RGB values, whichever the encoding.
    void dequantizeVertex(size_t v, std::vector<uint32_t>& idx, std::vector<float>& rgb) const {
        blocked() ? blocks.dequantizeVertex(v, idx, rgb) : vectors.dequantizeVertex(v, idx, rgb);
    }
    bool operator==(const TransportComponent&) const = default;
};

// The h_k view maps of the K-term phase factorisation (scalar cubemaps).
struct ViewMaps {
    int size = 0;   // face size, e.g. 16
    int terms = 0;  // K
    // terms x 6 x size x size floats, index ((k * 6 + face) * size + j) * size + i
    // (the Cubemap texel order of common/cubemap.h, one map after the other).
    std::vector<float> data;

    const float* term(int k) const { return data.data() + size_t(k) * 6 * size * size; }
    bool operator==(const ViewMaps&) const = default;
};

// The radial basis of a file with MultipleScatteringProfiles components, as stored:
// RadialBasis(range, tables) rebuilds the basis the precompute used, giving the same
// weights bit for bit. tables.size (J) is 3 x the number of profile components.
struct StoredRadialBasis {
    RadialRange range;
    RadialBasisTables tables;

    // Every field equal (the table values compared as floats).
    bool operator==(const StoredRadialBasis& other) const;
};

struct TransportFile {
    uint32_t cubemapSize = 0;  // N of the 6 x N x N lighting cubemap, power of two, 1..64
    // Terms of the SH part of every vector (common/sh_part.h): 0, 1, 4 or 9. Vectors
    // then have indices < 6 N^2 + shTerms, the last shTerms being SH coefficients that
    // relight against the light's SH projections (LightVector::sh).
    uint32_t shTerms = 0;
    MeshFingerprint mesh;
    double mmPerUnit = 1.0;  // scale that was applied to the mesh file's positions
    // Every precompute parameter as text (material, sigma_a, sigma_s', eta, g, terms,
    // epsilon, seed, sample count, tool version, ...), in the order given. Keys are
    // non-empty and unique.
    std::vector<std::pair<std::string, std::string>> parameters;
    std::vector<TransportComponent> components;
    std::optional<ViewMaps> viewMaps;  // present iff SingleScatteringTerm components exist
    // Present iff MultipleScatteringProfiles components exist (format version 5).
    std::optional<StoredRadialBasis> radialBasis;

    // The first SH index, 6 N^2, or UINT32_MAX when the vectors have no SH part: where
    // truncations keep terms first (jointTruncate's forcedFrom, foldVectors').
    uint32_t shIndexBegin() const { return shTerms > 0 ? 6 * cubemapSize * cubemapSize : UINT32_MAX; }

    // The component of that kind (and term), or nullptr.
    const TransportComponent* find(ComponentKind kind, uint32_t term = 0) const;
    // The value of a parameter, or "" when absent.
    std::string parameter(const std::string& key) const;
    bool hasParameter(const std::string& key) const;

    bool operator==(const TransportFile&) const = default;
};

// A shard file (prt-precompute --shard i/n, docs/cluster.md) is a transport file of the
// whole mesh whose vectors are empty outside one vertex range, with these two
// parameters: "shard" = "i/n" and "shard_vertices" = "begin-end" (end exclusive).
// prt-merge joins the n shards of a job into the whole file.
inline constexpr const char* kShardParameter = "shard";
inline constexpr const char* kShardVerticesParameter = "shard_vertices";

// Writes `file` to `path` atomically: validates it (one vertex count everywhere,
// equal to mesh.vertexCount; indices < 6 N^2 + shTerms and increasing; view maps present iff
// term components exist, one term component per view-map term; finite values; a
// blocked component passes checkBlockedVectors and has empty `vectors`; the radial
// basis present iff profile components exist, which are terms 0..P-1 with J = 3P, all
// per vertex sharing their offsets and indices or all blocked sharing their block
// order and SH scales, and the basis passes RadialBasis's construction), then writes
// through writeAtomically (common/atomic_file.h): on any failure an existing file at
// `path` is untouched, no temporary file is left and prt::Error(path, reason) is
// thrown. The format version is the lowest that holds the file: 7 with blocked profile
// components whose index lists differ, 6 with 8-bit profile components (SparseRgbVectors::haarBits; the writer stores
// the offsets and indices of a profile component equal to the one before it once), 5
// with a radial basis (whatever else it holds), else 4 with SH terms and a
// blocked component (varint indices, SH scales where BlockedRgbVectors::shFrom is
// set), 3 with SH terms, 2 with a blocked component, else 1, so older readers keep
// reading what needs nothing newer (docs/transport-format.md, "Compatibility").
// Deterministic: the same TransportFile gives the same bytes.
void saveTransportFile(const std::string& path, const TransportFile& file);

// Reads and verifies the whole file (every section's checksum, every count and
// index). Throws prt::Error(path, reason) for a missing file, a file that is not a
// transport file, an unsupported version or byte order, truncation (naming the
// section and the bytes it needs), a checksum mismatch (naming the section) or
// inconsistent contents. Allocations never exceed the file's size.
TransportFile loadTransportFile(const std::string& path);
// The same, but refuses (before reading the vectors) a file made for another mesh
// (naming both fingerprints), and a shard file (what the renderers load must be whole).
TransportFile loadTransportFile(const std::string& path, const MeshFingerprint& expected);

// What readTransportFileInfo returns: everything except the vectors and view maps.
struct TransportFileInfo {
    uint32_t version = 0;  // the file's format version, 1..7 (see saveTransportFile)
    uint32_t cubemapSize = 0;
    uint32_t shTerms = 0;
    MeshFingerprint mesh;
    double mmPerUnit = 1.0;
    std::vector<std::pair<std::string, std::string>> parameters;
    struct Component {
        ComponentKind kind = ComponentKind::MultipleScattering;
        uint32_t term = 0;
        uint64_t vertexCount = 0;
        // Per vertex: the coefficient count. Blocked: the count of shared indices (each
        // stands for one coefficient of each of the block's 16 lanes).
        uint64_t coefficientCount = 0;
        uint64_t payloadBytes = 0;  // bytes of the section's payload in the file
        bool blocked = false;       // a BLKC section (blocks of 16 vertices sharing indices)
        uint64_t blockCount = 0;    // blocked only: ceil(vertexCount / 16)
        bool shScales = false;      // blocked only: the SH part has scales of its own (version 4)
        bool eightBitHaar = false;  // per vertex only: 8-bit Haar values (version 6)
        bool sharedIndices = false; // 8-bit only: no indices of its own, the component before's
    };
    std::vector<Component> components;
    int viewMapSize = 0;   // 0 when the file has no view maps
    int viewMapTerms = 0;
    // The radial basis (version 5), from its section's fixed part; radialRange is empty
    // and radialProfiles 0 when the file has none. The range is checked by
    // validateRadialRange, the table values are neither read nor checked.
    std::optional<RadialRange> radialRange;
    int radialProfiles = 0;  // J
    int radialNodeCount = 0;
    RadialConstruction radialConstruction = RadialConstruction::Pca;
    double radialNormExponent = 0.0;
    uint64_t radialBasisBytes = 0;  // the section's payload in the file
    uint64_t fileBytes = 0;

    std::string parameter(const std::string& key) const;
    bool hasParameter(const std::string& key) const;
};

// Cheap look at a file (a few small reads, no large allocation): the preamble and the
// header and parameter sections (checksums verified), the fixed part of every
// component, view-map and radial-basis section and the end marker, and the profile
// components' terms against the basis size. The section structure is
// checked to span the file exactly, so a truncated file is refused; the large arrays
// are neither read nor checksummed (loadTransportFile does that).
TransportFileInfo readTransportFileInfo(const std::string& path);

// Multi-line human-readable summary (prt-relight info): N, mesh, parameters, components
// with vertex and coefficient counts (per vertex, or for a blocked component blocks and
// indices per block; mean, and max where the arrays are at hand) and bytes, view maps,
// and for a version-5 file a "radial basis:" line (J, construction, the z_r and alpha'
// range, eta, rMax, node count, the profile components' names).
// The first line is always a header line ("transport file..."). The bytes differ by
// source: describe(TransportFile) counts the in-memory arrays the relight streams
// (16-bit indices; labelled "in memory", with a "total:" line); describe(TransportFileInfo)
// counts the on-disk payload (labelled "on disk"): the same for per-vertex and version 2/3
// blocked components, smaller for version-4 blocked ones (delta-coded varint indices).
std::string describe(const TransportFile& file);
std::string describe(const TransportFileInfo& info);

}  // namespace prt
