#pragma once
// The mesostructure maps (include/dispmap/meso/march.h, MesoMaps) on the device: the five
// storage buffers shaders/meso/march.glsl reads, in its binding order, and the sizes it takes
// (DmMesoSize) with the root tolerance mesoRootTolerance<float>().
#include <array>
#include <cstdint>

#include "dispmap/meso/march.h"
#include "dispmap/vulkan/buffer.h"

namespace dispmap::vulkan {

/// DmMesoSize of march.glsl (std430 / push-constant layout: ten 4-byte fields).
struct MesoGpuSize {
    std::int32_t width = 0, height = 0, layers = 0, block = 0, gx = 0, gy = 0, gz = 0, coneM = 0, coneN = 0;
    float tol = 0;
};
static_assert(sizeof(MesoGpuSize) == 40);

/// The sizes of `maps` for the shader; ArgumentError when the maps disagree in size (or a
/// solid's lists do not cover its voxels).
MesoGpuSize mesoGpuSize(const MesoMaps& maps);

/// heights, distances, DDM grid, DDM atlas, column quadrics (march.glsl's bindings +0..+4),
/// then a solid's lists and triangles (packSolid: the two bindings from DM_MESO_SOLID_BINDING on). An empty map (e.g. no atlas block, a height
/// field's solid lists) becomes a 16-byte placeholder.
struct MesoBuffers {
    Buffer heights, distances, grid, atlas, quadrics, solidLists, solidTriangles;
    std::array<const Buffer*, 7> all() const { return {&heights, &distances, &grid, &atlas, &quadrics, &solidLists, &solidTriangles}; }
    std::size_t bytes = 0; ///< uploaded bytes
};

MesoBuffers uploadMesoMaps(Context& context, const MesoMaps& maps);

} // namespace dispmap::vulkan
