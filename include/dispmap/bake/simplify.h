#pragma once
// The simplification route to a base mesh (Lee, Moreton & Hoppe 2000, the "displaced
// subdivision surfaces" that Huang & Feng compare with): decimate the dense mesh to about N
// triangles by edge collapses under quadric error, with meshoptimizer's meshopt_simplify.
//
// Why meshoptimizer: it decimates millions of triangles in about a second on one core, keeps
// the original vertex positions (so the base mesh starts on the dense surface), and its
// collapses respect the topology of manifold input (borders, seams, and non-manifold "complex"
// vertices are locked). CGAL's edge collapse would guarantee a manifold result but takes
// minutes on a scan; OpenMesh's decimater refuses non-manifold input at reading.
//
// What a dense scan may still do to the result, and the rule for each: a triangle left on an
// edge that three or more triangles share (a non-manifold input edge) is dropped, as are
// triangles whose orientation disagrees with a neighbour's; a vertex where two fans of triangles
// touch (two cones meeting at a point) is split into one vertex per fan; components smaller than
// minComponentTriangles are dropped (dust). The result is then checked by ControlMesh.
#include <algorithm>
#include <cstdint>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include <meshoptimizer.h>

#include "dispmap/bake/dense_mesh.h"
#include "dispmap/surface/mesh.h"

namespace dispmap {

struct SimplifyOptions {
    int targetFaces = 500;          ///< triangles wanted (the base mesh's faces before the Catmull-Clark step)
    int minComponentTriangles = 8;  ///< smaller disconnected pieces are dropped
};

struct SimplifyReport {
    int faces = 0;              ///< triangles of the base mesh
    int droppedNonManifold = 0; ///< triangles dropped on edges of 3+ triangles or with a flipped orientation
    int droppedComponents = 0;  ///< pieces below minComponentTriangles
    int splitVertices = 0;      ///< copies made of vertices where two fans touched
    double meshoptError = 0;    ///< meshoptimizer's own (relative) error estimate
};

namespace detail {

/// Keeps at most two triangles per edge, and of those only pairs with opposite directions
/// (consistent orientation); returns the triangles kept.
inline std::vector<glm::uvec3> manifoldTriangles(const std::vector<glm::uvec3>& in, int& dropped) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed; // directed edge -> uses
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> undirected;
    std::vector<glm::uvec3> out;
    out.reserve(in.size());
    for (const glm::uvec3& t : in) {
        bool ok = true;
        for (int e = 0; e < 3 && ok; ++e) {
            const std::uint32_t a = t[e], b = t[(e + 1) % 3];
            if (directed.count({a, b}) || undirected[{std::min(a, b), std::max(a, b)}] >= 2) ok = false;
        }
        if (!ok) {
            ++dropped;
            continue;
        }
        for (int e = 0; e < 3; ++e) {
            const std::uint32_t a = t[e], b = t[(e + 1) % 3];
            directed[{a, b}] = 1;
            ++undirected[{std::min(a, b), std::max(a, b)}];
        }
        out.push_back(t);
    }
    return out;
}

/// Splits every vertex whose triangles form more than one fan (two cones touching at a point,
/// which collapses leave behind) into one vertex per fan, at the same position. Returns the
/// new triangles; `positions` grows by the copies.
inline std::vector<glm::uvec3> splitPinchedVertices(std::vector<glm::uvec3> tris, std::vector<glm::vec3>& positions, int& split) {
    if (tris.empty()) return tris; // (also keeps GCC 12's -Wnull-dereference quiet about parent(0))
    // wedge = (triangle, corner); wedges of one vertex are joined through the edges they share
    const std::size_t nw = tris.size() * 3;
    std::vector<std::size_t> parent(nw);
    std::iota(parent.begin(), parent.end(), std::size_t{0});
    auto find = [&](std::size_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::size_t> firstWedge; // (vertex, other end) -> a wedge
    for (std::size_t t = 0; t < tris.size(); ++t)
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t v = tris[t][c];
            const std::size_t w = 3 * t + static_cast<std::size_t>(c);
            for (const std::uint32_t other : {tris[t][(c + 1) % 3], tris[t][(c + 2) % 3]}) {
                const auto [it, fresh] = firstWedge.emplace(std::pair{v, other}, w);
                if (!fresh) parent[find(w)] = find(it->second);
            }
        }
    std::map<std::pair<std::uint32_t, std::size_t>, std::uint32_t> copyOf; // (vertex, fan) -> vertex id
    std::vector<char> used(positions.size(), 0);
    for (std::size_t t = 0; t < tris.size(); ++t)
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t v = tris[t][c];
            const std::size_t fan = find(3 * t + static_cast<std::size_t>(c));
            const auto it = copyOf.find({v, fan});
            if (it != copyOf.end()) {
                tris[t][c] = it->second;
                continue;
            }
            std::uint32_t id = v;
            if (used[v]) { // a second fan of v: a copy
                id = static_cast<std::uint32_t>(positions.size());
                positions.push_back(positions[v]);
                ++split;
            }
            used[v] = 1;
            copyOf.emplace(std::pair{v, fan}, id);
            tris[t][c] = id;
        }
    return tris;
}

} // namespace detail

/// The decimated dense mesh as a control mesh description (triangles, counter-clockwise as in
/// the dense mesh). Throws ArgumentError for a target below 4 faces, MeshError when nothing
/// manifold is left.
inline MeshDescription simplifiedControlMesh(const DenseMesh& dense, const SimplifyOptions& options = {},
                                             SimplifyReport* report = nullptr) {
    if (options.targetFaces < 4) throw ArgumentError("simplification: the base mesh needs at least 4 faces");
    if (dense.triangles.empty() || dense.positions.empty()) throw ArgumentError("simplification: the dense mesh is empty");
    SimplifyReport rep;
    std::vector<unsigned> indices(dense.triangles.size() * 3);
    for (std::size_t i = 0; i < dense.triangles.size(); ++i)
        for (int c = 0; c < 3; ++c) indices[3 * i + static_cast<std::size_t>(c)] = dense.triangles[i][c];
    std::vector<unsigned> out(indices.size());
    float err = 0.0f;
    // No error bound: the face count is the target (the base mesh's size is the user's choice).
    const std::size_t n = meshopt_simplify(out.data(), indices.data(), indices.size(), &dense.positions[0].x,
                                           dense.positions.size(), sizeof(glm::vec3),
                                           static_cast<std::size_t>(options.targetFaces) * 3, 1e30f, 0, &err);
    rep.meshoptError = static_cast<double>(err);
    std::vector<glm::uvec3> tris(n / 3);
    for (std::size_t i = 0; i < tris.size(); ++i) tris[i] = glm::uvec3(out[3 * i], out[3 * i + 1], out[3 * i + 2]);
    // Degenerate results (a collapse may leave two corners on one vertex) carry no surface.
    tris.erase(std::remove_if(tris.begin(), tris.end(), [](const glm::uvec3& t) { return t.x == t.y || t.y == t.z || t.x == t.z; }),
               tris.end());
    tris = detail::manifoldTriangles(tris, rep.droppedNonManifold);
    std::vector<glm::vec3> positions = dense.positions;
    tris = detail::splitPinchedVertices(std::move(tris), positions, rep.splitVertices);

    // Components by union-find over shared vertices; dust goes.
    std::vector<std::uint32_t> parent(positions.size());
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](std::uint32_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    for (const glm::uvec3& t : tris) {
        parent[find(t.y)] = find(t.x);
        parent[find(t.z)] = find(t.x);
    }
    std::map<std::uint32_t, int> size;
    for (const glm::uvec3& t : tris) ++size[find(t.x)];
    for (const auto& [root, count] : size) rep.droppedComponents += count < options.minComponentTriangles ? 1 : 0;
    std::vector<glm::uvec3> kept;
    for (const glm::uvec3& t : tris)
        if (size[find(t.x)] >= options.minComponentTriangles) kept.push_back(t);

    MeshDescription d;
    d.name = dense.name + " (simplified to " + std::to_string(kept.size()) + " triangles)";
    std::vector<int> remap(positions.size(), -1);
    for (const glm::uvec3& t : kept) {
        d.faceSizes.push_back(3);
        for (int c = 0; c < 3; ++c) {
            int& r = remap[t[c]];
            if (r < 0) {
                r = static_cast<int>(d.positions.size());
                d.positions.emplace_back(positions[t[c]]);
            }
            d.faceVertices.push_back(r);
        }
    }
    if (kept.empty())
        throw MeshError(dense.name + ": nothing manifold is left after simplifying to " + std::to_string(options.targetFaces) +
                        " faces; try more faces or the skeleton route");
    rep.faces = static_cast<int>(kept.size());
    if (report) *report = rep;
    return d;
}

} // namespace dispmap
