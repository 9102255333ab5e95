#pragma once
// Shared helpers of the tests: meshes from tests/data and generated ones.
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "dispmap/surface/builtin.h"
#include "dispmap/surface/tile_builder.h"

namespace dmtest {

inline std::string dataPath(const std::string& file) {
    // Appended piecewise: GCC 12 at -O2 reports a false -Warray-bounds inside libstdc++ for
    // std::string(literal) + "/" + file in some translation units.
    std::string path = DISPMAP_TEST_DATA;
    path += '/';
    path += file;
    return path;
}

inline dispmap::ControlMesh shape(const std::string& name) {
    return dispmap::ControlMesh::fromObjFile(dataPath(name + ".obj"));
}

/// The mesh with a random third of its interior edges infinitely sharp (sharpness 10) and a
/// few vertices infinitely sharp corners: creases that end inside the surface (darts), meet
/// at corners, run along boundaries of N-gons, next to smooth edges whose end vertices they touch.
inline dispmap::ControlMesh withSharpFeatures(const dispmap::ControlMesh& mesh, std::uint32_t seed) {
    dispmap::MeshDescription d = mesh.description();
    d.name += " (random sharp features)";
    const OpenSubdiv::Far::TopologyLevel& L = mesh.base();
    std::mt19937 rng(seed);
    for (int e = 0; e < L.GetNumEdges(); ++e) {
        if (L.IsEdgeBoundary(e) || rng() % 3 != 0) continue;
        d.creaseVertexPairs.push_back(L.GetEdgeVertices(e)[0]);
        d.creaseVertexPairs.push_back(L.GetEdgeVertices(e)[1]);
        d.creaseWeights.push_back(10.0f);
    }
    for (int v = 0; v < L.GetNumVertices(); ++v)
        if (rng() % 11 == 0) {
            d.cornerVertices.push_back(v);
            d.cornerWeights.push_back(10.0f);
        }
    return dispmap::ControlMesh(std::move(d));
}

/// An n x m torus of quads (every vertex valence 4, no boundary), u along i, v along j.
inline std::string torusObj(int n, int m) {
    std::string s;
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < n; ++i) {
            const double a = 6.283185307179586 * i / n, b = 6.283185307179586 * j / m;
            s += "v " + std::to_string((2 + std::cos(b)) * std::cos(a)) + " " + std::to_string((2 + std::cos(b)) * std::sin(a)) +
                 " " + std::to_string(std::sin(b)) + "\n";
        }
    auto id = [&](int i, int j) { return ((j % m + m) % m) * n + ((i % n + n) % n) + 1; };
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < n; ++i)
            s += "f " + std::to_string(id(i, j)) + " " + std::to_string(id(i + 1, j)) + " " + std::to_string(id(i + 1, j + 1)) +
                 " " + std::to_string(id(i, j + 1)) + "\n";
    return s;
}

/// An n x m grid of quads in the plane z = 0 with texture coordinates (x/n, y/m).
inline std::string gridObj(int n, int m) {
    std::string s;
    for (int j = 0; j <= m; ++j)
        for (int i = 0; i <= n; ++i) {
            s += "v " + std::to_string(i) + " " + std::to_string(j) + " 0\n";
            s += "vt " + std::to_string(double(i) / n) + " " + std::to_string(double(j) / m) + "\n";
        }
    auto id = [&](int i, int j) { return std::to_string(j * (n + 1) + i + 1); };
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < n; ++i) {
            std::string a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
            s += "f " + a + "/" + a + " " + b + "/" + b + " " + c + "/" + c + " " + d + "/" + d + "\n";
        }
    return s;
}

/// Length of the bounding-box diagonal of the cage: the scale of position tolerances.
inline double extentOf(const dispmap::ControlMesh& mesh) {
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (const glm::dvec3& p : mesh.description().positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    return glm::length(hi - lo);
}

/// A fan of n quads around a centre vertex (builtin::fanObj).
using dispmap::builtin::fanObj;

/// Data that is deliberately discontinuous between faces: the tile format must make D C1
/// across every edge whatever the samples are.
inline double roughSource(int face, double u, double v) {
    return 0.3 * std::sin(7.0 * u + 1.3 * face) * std::cos(5.0 * v - 0.7 * face) + 0.05 * face;
}

/// The (u, v) on tile edge e at edge parameter y, and the inward direction.
inline glm::dvec2 edgePoint(int e, double y) {
    switch (e & 3) {
    case 0: return {y, 0.0};
    case 1: return {1.0, y};
    case 2: return {1.0 - y, 1.0};
    default: return {0.0, 1.0 - y};
    }
}
inline glm::dvec2 inward(int e) {
    switch (e & 3) {
    case 0: return {0.0, 1.0};
    case 1: return {-1.0, 0.0};
    case 2: return {0.0, -1.0};
    default: return {1.0, 0.0};
    }
}
inline glm::dvec2 along(int e) {
    switch (e & 3) {
    case 0: return {1.0, 0.0};
    case 1: return {0.0, 1.0};
    case 2: return {-1.0, 0.0};
    default: return {0.0, -1.0};
    }
}

/// The level of a tile at global resolution g (log2 texels per base edge), or -1.
inline int levelAt(const dispmap::TileSet& ts, const dispmap::TileTopology& topo, int t, int g) {
    const int k = ts.tiles[static_cast<std::size_t>(t)].k;
    const int m = k + topo.scale(t) - g;
    return (m >= 0 && m < k) ? m : -1;
}

} // namespace dmtest
