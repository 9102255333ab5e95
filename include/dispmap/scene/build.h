#pragma once
// Building what a scene names (scene/scene.h): its control mesh (built-in or OBJ) and its tile
// set (a saved tile file, a UV-mapped height image or a procedural function).
#include <optional>
#include <string>
#include <vector>

#include "dispmap/core/error.h"
#include "dispmap/io/png.h"
#include "dispmap/io/tile_file.h"
#include "dispmap/scene/scene.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/mesh.h"
#include "dispmap/surface/tile_builder.h"

namespace dispmap {

/// Tile sizes with mixed sizes on one mesh (§4.4): quads get k - (ptex face % 3), at least
/// kMinTileLog2, and sub-faces of non-quads k - 1 as in uniformTileSizes. A quad touching
/// either end of an edge it or another quad shares with a non-quad face keeps k: the builder
/// needs the quad at a T-junction to have k and no smaller tile at the edge's ends. Throws
/// ArgumentError as uniformTileSizes.
inline std::vector<int> mixedTileSizes(const ControlMesh& mesh, int k) {
    std::vector<int> out = uniformTileSizes(mesh, k);
    const Far::TopologyLevel& L = mesh.base();
    std::vector<std::uint8_t> pinned(static_cast<std::size_t>(L.GetNumVertices()), 0);
    for (int e = 0; e < L.GetNumEdges(); ++e) {
        bool quad = false, other = false;
        for (int f : L.GetEdgeFaces(e)) (L.GetFaceVertices(f).size() == 4 ? quad : other) = true;
        if (!(quad && other)) continue;
        for (int v : L.GetEdgeVertices(e)) pinned[static_cast<std::size_t>(v)] = 1;
    }
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        if (L.GetFaceVertices(f).size() != 4) continue;
        bool keep = false;
        for (int v : L.GetFaceVertices(f)) keep = keep || pinned[static_cast<std::size_t>(v)] != 0;
        const int t = mesh.ptex().GetFaceId(f);
        if (!keep) out[static_cast<std::size_t>(t)] = std::max(kMinTileLog2, k - t % 3);
    }
    return out;
}

/// The scene's control mesh: a built-in one, or the OBJ file (resolved against baseDir).
/// Throws SceneError for an unknown built-in, FileError / MeshError for the file.
inline ControlMesh sceneMesh(const Scene& scene) {
    if (scene.mesh.rfind("builtin:", 0) == 0) {
        try {
            return builtin::builtinMesh(scene.mesh.substr(8));
        } catch (const ArgumentError& e) {
            throw SceneError("scene '" + scene.name + "': mesh: " + e.what());
        }
    }
    if (scene.mesh.empty()) throw SceneError("scene '" + scene.name + "': mesh: empty");
    return ControlMesh::fromObjFile(resolveScenePath(scene, scene.mesh));
}

/// The tile set of `mesh` that `d` describes, its paths ready to open: loaded from the tile
/// file, or built from the height image or the procedural function with tile sizes 2^k
/// (mixedTileSizes if mixedSizes) and the mip filter (`dispmap tiles` and sceneTiles). The
/// scale and offset are checked first (displacementProblem: |offset| + |scale| <=
/// kMaxDisplacement), before any file is read.
/// `report` (if given) receives the fit's report when tiles are built. Throws FileError for a
/// file that cannot be read, ArgumentError naming the field ("displacement.tiles: ...",
/// "displacement: <builder's reason>") for a tile file of another mesh, an unknown function or
/// filter, and what the builder rejects (sizes, a mesh without texture coordinates for a
/// height image, NaN samples).
inline TileSet displacementTiles(const ControlMesh& mesh, const SceneDisplacement& d, BuildReport* report = nullptr) {
    if (!d.tiles.empty()) {
        TileSet ts = loadTiles(d.tiles);
        if (topologyHash(mesh) != ts.topologyHash || mesh.ptexFaceCount() != ts.tileCount())
            throw ArgumentError("displacement.tiles: '" + d.tiles + "' was built for another mesh than '" +
                                mesh.description().name + "'");
        return ts;
    }
    if (const std::optional<DrawProblem> p = displacementProblem(d)) throw ArgumentError(p->key + ": " + p->why);
    if (d.height.empty() && d.function != "waves" && d.function != "zero")
        throw ArgumentError("displacement.function: unknown value '" + d.function + "' (waves, zero)");
    BuildOptions o;
    if (d.filter == "haar")
        o.filter = MipFilter::Haar;
    else if (d.filter == "bwavelet")
        o.filter = MipFilter::BWavelet;
    else
        throw ArgumentError("displacement.filter: unknown value '" + d.filter + "' (haar, bwavelet)");
    try {
        DisplacementFunction source;
        if (!d.height.empty()) {
            auto img = std::make_shared<HeightImage>(readHeightPng(d.height));
            source = imageSource(mesh, img, d.scale, d.offset, d.wrap);
        } else if (d.function == "waves") {
            const double s = d.scale;
            source = [s](int f, double u, double v) { return s * builtin::defaultDisplacement(f, u, v) / 0.07; };
        } else {
            source = [](int, double, double) { return 0.0; };
        }
        const std::vector<int> k = d.mixedSizes ? mixedTileSizes(mesh, d.k) : uniformTileSizes(mesh, d.k);
        return buildTiles(mesh, k, source, o, report);
    } catch (const ArgumentError& e) {
        throw ArgumentError(std::string("displacement: ") + e.what());
    }
}

/// The scene's tile set on `mesh` (sceneMesh): displacementTiles with the paths resolved
/// against the scene's directory. Throws FileError for a file that cannot be read, SceneError
/// (naming the scene) for everything displacementTiles rejects.
inline TileSet sceneTiles(const Scene& scene, const ControlMesh& mesh, BuildReport* report = nullptr) {
    SceneDisplacement d = scene.displacement;
    if (!d.tiles.empty()) d.tiles = resolveScenePath(scene, d.tiles);
    if (!d.height.empty()) d.height = resolveScenePath(scene, d.height);
    try {
        return displacementTiles(mesh, d, report);
    } catch (const ArgumentError& e) {
        throw SceneError("scene '" + scene.name + "': " + e.what());
    }
}

} // namespace dispmap
