// Upload of the mesostructure maps for shaders/meso/march.glsl.
#include "dispmap/vulkan/meso_maps.h"

#include <algorithm>
#include <string>
#include <vector>

namespace dispmap::vulkan {

MesoGpuSize mesoGpuSize(const MesoMaps& maps) {
    const MesoHeightField& f = maps.field;
    const auto same = [&](int w, int h, int l) { return w == f.width && h == f.height && l == f.layers; };
    if (f.width < 2 || f.height < 2 || f.layers < 2 || !same(maps.distance.width, maps.distance.height, maps.distance.layers) ||
        !same(maps.ddm.width, maps.ddm.height, maps.ddm.layers) || maps.quadrics.width != f.width || maps.quadrics.height != f.height)
        throw ArgumentError("mesostructure maps: the height field, distance map, DDM and quadrics differ in size (build them with "
                            "buildMesoMaps)");
    if (maps.isSolid() &&
        (!same(maps.solid.width, maps.solid.height, maps.solid.layers) ||
         maps.solid.entryStart.size() != static_cast<std::size_t>(f.width) * static_cast<std::size_t>(f.height) * static_cast<std::size_t>(f.layers) + 1 ||
         maps.solid.entryStart.back() != maps.solid.entries.size()))
        throw ArgumentError("mesostructure maps: the solid's triangle lists do not match its maps (build them with buildMesoSolidMaps)");
    if (!maps.isSolid() && f.h.size() != static_cast<std::size_t>(f.width) * static_cast<std::size_t>(f.height))
        throw ArgumentError("mesostructure maps: the height field has no heights");
    MesoGpuSize s;
    s.width = f.width;
    s.height = f.height;
    s.layers = f.layers;
    s.block = maps.ddm.block;
    s.gx = maps.ddm.gx;
    s.gy = maps.ddm.gy;
    s.gz = maps.ddm.gz;
    s.coneM = maps.ddm.cones.kernelM();
    s.coneN = maps.ddm.cones.n;
    s.tol = mesoRootTolerance<float>();
    return s;
}

namespace {
template <class T> Buffer uploadVector(Context& ctx, const std::vector<T>& v, std::size_t& bytes) {
    const std::size_t n = v.size() * sizeof(T);
    Buffer b(ctx, std::max<std::size_t>(n, 16));
    if (n) b.upload(v.data(), n);
    bytes += n;
    return b;
}
} // namespace

MesoBuffers uploadMesoMaps(Context& ctx, const MesoMaps& maps) {
    (void)mesoGpuSize(maps); // validates
    std::size_t bytes = 0;
    const PackedSolid solid = maps.isSolid() ? packSolid(maps.solid) : PackedSolid{};
    std::vector<float> atlas = maps.ddm.atlas; // the atlas buffer: the blocks, then the plane records
    atlas.insert(atlas.end(), maps.ddm.planes.begin(), maps.ddm.planes.end());
    MesoBuffers b{uploadVector(ctx, maps.field.h, bytes), uploadVector(ctx, maps.distance.d, bytes),
                  uploadVector(ctx, maps.ddm.grid, bytes), uploadVector(ctx, atlas, bytes),
                  uploadVector(ctx, maps.quadrics.q, bytes), uploadVector(ctx, solid.lists, bytes),
                  uploadVector(ctx, solid.triangles, bytes), 0};
    b.bytes = bytes;
    return b;
}

} // namespace dispmap::vulkan
