#pragma once
// A mesostructure scene (scene/meso.h) made ready for the MesoRenderer: the base, and each of
// its mesostructures' maps, images and look as a MesoPart over its triangles. Shared by
// `dispmap render`, `dispmap meso --curved` and the viewer.
#include <memory>
#include <vector>

#include "dispmap/scene/meso.h"
#include "dispmap/vulkan/meso_renderer.h"

namespace dispmap::figures {

/// The look of one of the scene's mesostructures: technique, shadows, slab, checker, the
/// normal map's scale and green (its images are built apart: buildMesoSceneAlbedo,
/// buildMesoSceneNormals).
inline vulkan::MesoLook mesoSceneLook(const MesoSceneDesc& s) {
    vulkan::MesoLook o;
    o.technique = s.technique;
    o.shadows = s.shadows;
    o.depth = s.slab;
    o.checkerVoxels = s.checker;
    o.normalScale = s.normalScale;
    o.normalGreenUp = s.normalGreenUp;
    return o;
}

/// The renderer's options a scene states: image size, camera, light, tile, and its first
/// mesostructure's look; its base and images are built apart (buildMesoSceneBase, ...),
/// frames are the caller's.
inline vulkan::MesoRenderOptions mesoSceneRenderOptions(const MesoSceneDesc& s) {
    vulkan::MesoRenderOptions o;
    static_cast<vulkan::MesoLook&>(o) = mesoSceneLook(s);
    o.width = s.width;
    o.height = s.height;
    o.camera.eye = s.eye;
    o.camera.target = s.target;
    o.camera.up = s.up;
    o.camera.fovYDeg = s.fov;
    o.lightDirection = s.light;
    o.tileSize = s.tile;
    o.silhouettes = s.silhouettes;
    o.bentRays = s.bentRays;
    return o;
}

/// Everything of a scene the renderer draws: `parts` point into `maps` (moving keeps them
/// valid; copying would not, so it is deleted).
struct MesoSceneGpu {
    std::vector<MesoSceneDesc> descs; ///< mesoSceneParts
    std::vector<MesoMaps> maps;       ///< one a mesostructure
    std::vector<vulkan::MesoPart> parts;
    vulkan::MesoRenderOptions options; ///< the scene's, with its base
    MesoSceneGpu() = default;
    MesoSceneGpu(MesoSceneGpu&&) = default;
    MesoSceneGpu& operator=(MesoSceneGpu&&) = default;
    MesoSceneGpu(const MesoSceneGpu&) = delete;
    MesoSceneGpu& operator=(const MesoSceneGpu&) = delete;
};

/// Builds the base (buildMesoSceneBase), then each mesostructure's maps, albedo and normal map
/// and its part of the base's triangles. Throws what those throw.
inline MesoSceneGpu buildMesoSceneGpu(const MesoSceneDesc& s) {
    MesoSceneGpu g;
    g.descs = mesoSceneParts(s);
    g.options = mesoSceneRenderOptions(s);
    g.options.base = buildMesoSceneBase(s);
    g.maps.reserve(g.descs.size()); // the parts point into it
    for (std::size_t i = 0; i < g.descs.size(); ++i) {
        vulkan::MesoPart& p = g.parts.emplace_back();
        p.maps = &g.maps.emplace_back(buildMesoSceneMaps(g.descs[i]));
        p.look = mesoSceneLook(g.descs[i]);
        p.look.albedo = buildMesoSceneAlbedo(g.descs[i]);
        p.look.normalMap = buildMesoSceneNormals(g.descs[i], g.options.base.get());
        const FrameMesh* base = g.options.base.get();
        p.triangles = !base ? 2 * g.options.quads * g.options.quads : base->groups.empty() ? base->triangleCount() : base->groups[i];
    }
    return g;
}

} // namespace dispmap::figures
