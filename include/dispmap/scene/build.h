#pragma once
// Building what a scene names (scene/scene.h): its control mesh (built-in or OBJ) and its tile
// set (a saved tile file, a UV-mapped height image or a procedural function).
#include <optional>
#include <string>
#include <vector>

#include "dispmap/core/error.h"
#include "dispmap/io/image_files.h"
#include "dispmap/io/png.h"
#include "dispmap/io/tile_file.h"
#include "dispmap/scene/scene.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/map_source.h"
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
    const std::vector<char> pinned = quadsPinnedByNonQuads(mesh);
    const Far::TopologyLevel& L = mesh.base();
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        if (L.GetFaceVertices(f).size() != 4 || pinned[static_cast<std::size_t>(f)]) continue;
        const int t = mesh.ptex().GetFaceId(f);
        out[static_cast<std::size_t>(t)] = std::max(kMinTileLog2, k - t % 3);
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
/// file, or built from the height image (one image or a UDIM set: io/image_files.h, placed
/// through the UV rule `uv` with the map filter: surface/map_source.h) or the procedural
/// function, with tile sizes 2^k (mixedTileSizes if mixedSizes, texelTileSizes up to k if
/// sizes is "texels", errorTileSizes up to k within sizeTolerance x |scale| if "error") and the
/// mip filter (`dispmap tiles` and sceneTiles). The
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
    const std::optional<UvInterpolation> uvRule = parseUvInterpolation(d.uv);
    if (!uvRule) throw ArgumentError("displacement.uv: unknown value '" + d.uv + "' (" + uvInterpolationNames() + ")");
    const std::optional<MapFilter> mapFilter = parseMapFilter(d.mapFilter);
    if (!mapFilter) throw ArgumentError("displacement.mapFilter: unknown value '" + d.mapFilter + "' (point, box, tent)");
    if (d.sizes != "uniform" && d.sizes != "texels" && d.sizes != "error")
        throw ArgumentError("displacement.sizes: unknown value '" + d.sizes + "' (uniform, texels, error)");
    if (d.sizes != "uniform" && d.height.empty()) throw ArgumentError("displacement.sizes: \"" + d.sizes + "\" needs a height image");
    if (d.sizes != "uniform" && d.mixedSizes) throw ArgumentError("displacement: give mixedSizes or sizes \"" + d.sizes + "\", not both");
    if (!(d.sizeTolerance > 0.0 && d.sizeTolerance <= 1.0))
        throw ArgumentError("displacement.sizeTolerance: " + std::to_string(d.sizeTolerance) + " is not in (0, 1] (the map's height units)");
    if (!std::isfinite(d.midLevel) || std::abs(d.midLevel) > kMaxDisplacement)
        throw ArgumentError("displacement.midLevel: must be finite, at most " + std::to_string(kMaxDisplacement) + " in size");
    try {
        DisplacementFunction source;
        std::vector<int> k;
        if (!d.height.empty()) {
            HeightReadOptions ro;
            ro.channel = d.channel;
            const HeightMaps maps = readHeightMaps(d.height, ro);
            auto uvs = std::make_shared<const UvMap>(mesh, *uvRule);
            MapSourceOptions mo;
            mo.scale = d.scale;
            mo.offset = d.offset;
            mo.midLevel = d.midLevel;
            mo.wrap = d.wrap;
            mo.filter = *mapFilter;
            mo.allowOverlap = d.allowOverlap;
            k = d.sizes == "texels" ? texelTileSizes(mesh, *uvs, maps, kMinTileLog2, d.k)
                : d.sizes == "error" ? errorTileSizes(mesh, uvs, maps, kMinTileLog2, d.k, d.sizeTolerance * std::abs(d.scale), mo)
                : d.mixedSizes      ? mixedTileSizes(mesh, d.k)
                                    : uniformTileSizes(mesh, d.k);
            DisplacementFunction mapped = mapSource(uvs, maps, k, mo);
            // float heights are not bounded by [0, 1]: the displacement's bound is checked per sample
            source = [mapped = std::move(mapped)](int f, double u, double v) {
                const double x = mapped(f, u, v);
                if (std::abs(x) > kMaxDisplacement)
                    throw ArgumentError("the height image gives a displacement of " + std::to_string(x) + " at Ptex face " +
                                        std::to_string(f) + ", beyond " + std::to_string(kMaxDisplacement) +
                                        " (check scale and midLevel)");
                return x;
            };
            return buildTiles(mesh, k, source, o, report);
        } else if (d.function == "waves") {
            const double s = d.scale;
            source = [s](int f, double u, double v) { return s * builtin::defaultDisplacement(f, u, v) / 0.07; };
        } else {
            source = [](int, double, double) { return 0.0; };
        }
        k = d.mixedSizes ? mixedTileSizes(mesh, d.k) : uniformTileSizes(mesh, d.k);
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
