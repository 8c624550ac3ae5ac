#pragma once
// Small procedural meshes for tests and demos that need no downloaded data. All are
// closed, counter-clockwise seen from outside, centred at the origin, with +Y up,
// and carry exact analytic unit normals (not computeVertexNormals' estimate).
// Invalid parameters throw prt::Error with the generator's name as subject.

#include "common/mesh.h"

namespace prt {

// Icosahedron subdivided `subdivisions` times (0..10), every vertex projected onto the
// sphere of `radius` > 0. Vertices are shared: 10 * 4^n + 2 vertices, 20 * 4^n
// triangles. Normals are the normalised positions.
TriangleMesh makeIcosphere(int subdivisions, float radius);

// Axis-aligned box of the given size (all components > 0), centred at the origin.
// Each of the 6 faces has its own vertices (so normals are flat and split at the
// edges): a grid of segments[a] x segments[b] cells over the face's two axes a, b.
// With the default one segment per axis: 24 vertices, 12 triangles. Coincident
// positions on shared edges are bit-identical, so the box is closed once coincident
// vertices are welded (analyseTopology(mesh, true)).
TriangleMesh makeBox(glm::vec3 size, glm::ivec3 segments = glm::ivec3(1));

// A flat slab: makeBox({width, thickness, depth}, {cells, 1, cells}); the top face
// (+Y, at y = thickness / 2) is a cells x cells grid.
TriangleMesh makeSlab(float width, float depth, float thickness, int cells);

// Torus around the Y axis: ring radius R (centre of the tube), tube radius r,
// 0 < r < R; nu >= 3 segments around the ring, nv >= 3 around the tube.
// nu * nv shared vertices, 2 * nu * nv triangles. Area tends to 4 pi^2 R r and
// volume to 2 pi^2 R r^2 as nu, nv grow.
TriangleMesh makeTorus(float R, float r, int nu, int nv);

}  // namespace prt
