#pragma once
// SceneSurface: what a scene file describes, built once and kept together: the control mesh,
// its tiles, the base and displaced surfaces, and (for the traditional baseline) the baked
// height and normal atlas. The surfaces point at the mesh and tiles, so it does not move.
#include <optional>

#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/baseline.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/scene/build.h"
#include "dispmap/scene/scene.h"

namespace dispmap {

struct SceneSurface {
    ControlMesh mesh;
    TileSet tiles;
    BaseSurface base;
    DisplacedSurface surface;
    std::optional<BaselineAtlas> atlas;
    BaselineLayout bakedLayout = BaselineLayout::Faces; ///< what `atlas` was baked for
    int bakedTexels = 0;

    /// Builds the mesh and tiles of `scene` (sceneMesh, sceneTiles), its surfaces at the
    /// scene's isolation level, end caps and auto tolerance, and the baseline atlas if the scene's
    /// technique is the baseline. Throws what those throw (FileError, MeshError, SceneError...).
    explicit SceneSurface(const Scene& scene)
        : mesh(sceneMesh(scene)), tiles(sceneTiles(scene, mesh)), base(mesh, baseOptions(scene)),
          surface(base, tiles, displacedOptions(scene)) {
        if (scene.effects.technique == Technique::Baseline) bake(scene);
    }
    SceneSurface(const SceneSurface&) = delete;
    SceneSurface& operator=(const SceneSurface&) = delete;

    /// The baseline atlas at the scene's texel density (baselineTexels, or 2^k per face edge)
    /// in the scene's layout (the mesh-UV layout with as many texels, its UVs interpolated
    /// linearly), baked on first use and again when the scene asks for another layout or
    /// density. The UV layout throws ArgumentError for a mesh without UVs.
    const BaselineAtlas& bake(const Scene& scene) {
        const int n = scene.baselineTexels > 0 ? scene.baselineTexels : 1 << scene.displacement.k;
        if (atlas && bakedLayout == scene.baselineLayout && bakedTexels == n) return *atlas;
        bakedLayout = scene.baselineLayout;
        bakedTexels = n;
        if (scene.baselineLayout == BaselineLayout::MeshUv) {
            const int side = baselineUvSide(base.faceCount(), n);
            atlas = bakeBaselineUv(surface, UvMap(mesh, UvInterpolation::Linear), side, side);
        } else {
            atlas = bakeBaseline(surface, n);
        }
        return *atlas;
    }

    static BaseSurfaceOptions baseOptions(const Scene& scene) {
        BaseSurfaceOptions o;
        o.isolationLevel = scene.isolation;
        o.gregoryEndCaps = scene.gregoryEndCaps;
        return o;
    }
    static DisplacedSurfaceOptions displacedOptions(const Scene& scene) {
        DisplacedSurfaceOptions o;
        o.autoTolerance = scene.effects.autoToleranceDeg * 3.14159265358979323846 / 180.0;
        o.sharpBand = scene.displacement.sharpBand;
        return o;
    }
};

} // namespace dispmap
