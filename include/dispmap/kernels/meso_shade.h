#pragma once
// Kernels of the mesostructure renderer (backend_vulkan MesoRenderer, shaders/meso/): the
// pixel ray's entry into voxel space, the normal of the bilinear height field at a hit, the
// shadow ray's origin and the shading. Voxel space as in kernels/meso.h; the base surface is
// the plane z = 0 with tangent +x, bitangent +y and normal +z, so tangent space is world
// space and voxelsPerUnit = (W / tile size, H / tile size, L / depth) in world units.
#include "dispmap/kernels/sum.h"
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin
// Where the pixel's ray enters the slab: the base-surface point (world x, y on the plane)
// in voxel units, on the top plane z = L.
DM_TFUNC rvec3 dmMesoEntry(rvec3 worldPos, rvec3 voxelsPerUnit, int L) {
    return rvec3(worldPos.x * voxelsPerUnit.x, worldPos.y * voxelsPerUnit.y, real(L));
}

// The gradient (dH/dx, dH/dy) of the bilinear patch with corners h (dmBilerp's order) at the
// fraction f, in voxels per voxel.
DM_TFUNC rvec2 dmMesoHeightGradient(rvec4 h, rvec2 f) {
    real gx = (real(1) - f.y) * (h.y - h.x) + f.y * (h.z - h.w);
    real gy = (real(1) - f.x) * (h.w - h.x) + f.x * (h.z - h.y);
    return rvec2(gx, gy);
}

// The unit normal of the height field in tangent (world) space: the voxel-space slopes scaled
// by (voxels per unit in x or y) / (voxels per unit in z).
DM_TFUNC rvec3 dmMesoWorldNormal(rvec4 h, rvec2 f, rvec3 voxelsPerUnit) {
    rvec2 g = dmMesoHeightGradient(h, f);
    rvec3 n = rvec3(-g.x * (voxelsPerUnit.x / voxelsPerUnit.z), -g.y * (voxelsPerUnit.y / voxelsPerUnit.z), real(1));
    return n * (real(1) / sqrt(dmDot3(n, n)));
}

// The shadow ray's origin: the hit point lifted by `offset` voxels along the voxel-space
// normal of the height field, so the ray does not start on (or, after rounding, under) the
// surface it leaves.
DM_TFUNC rvec3 dmMesoShadowOrigin(rvec3 p, rvec4 h, rvec2 f, real offset) {
    rvec2 g = dmMesoHeightGradient(h, f);
    rvec3 n = rvec3(-g.x, -g.y, real(1));
    return p + n * (offset / sqrt(dmDot3(n, n)));
}

// Albedo of a checker of `period` voxels (1 and 0.55), so the parallax is visible.
DM_TFUNC real dmMesoChecker(rvec2 p, real period) {
    int a = int(floor(p.x / period)) + int(floor(p.y / period));
    return (a & 1) == 0 ? real(1) : real(0.55);
}

// Lambert with an ambient term: albedo (ambient + (1 - ambient) max(n . l, 0) lit), l unit,
// lit 0 in shadow and 1 in light.
DM_TFUNC real dmMesoShade(real albedo, rvec3 n, rvec3 l, real ambient, real lit) {
    return albedo * (ambient + ((real(1) - ambient) * max(dmDot3(n, l), real(0))) * lit);
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
