#pragma once
// Kernels of the mesostructure renderer (backend_vulkan MesoRenderer, shaders/meso/): the
// pixel ray's entry into voxel space, the normal of the bilinear height field at a hit, the
// shadow ray's origin, a normal map's normal and the shading. Voxel space as in
// kernels/meso.h. On the plane z = 0 (tangent +x, bitangent +y, normal +z) tangent space is
// world space and voxelsPerUnit = (W / tile size, H / tile size, L / depth) in world units.
// On any other base (a curved surface, Donnelly §8.3.1: locally planar) each pixel has a frame
// (dmFrameCoordinates): the world vectors pS = dP/ds and pT = dP/dt along the mesostructure's
// texture coordinates (s, t), one unit a tile, and the unit normal n; there voxelsPerUnit =
// (W, H, L / depth) (voxels per texture unit in s and t, per world unit along n), and
// dmFramePoint / dmFrameNormal take the hit and the height field's normal back to the world.
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

// --- Curved bases: the pixel's frame (pS, pT, n) ------------------------------------------
// The coordinates (a, b, c) of the world vector w in the frame, w = a pS + b pT + c n
// (Cramer's rule; a, b in texture units, c in world units). The caller passes a frame whose
// pS, pT and n are independent (the base mesh's builder checks: surface/frame_mesh.h); a
// mirrored chart (pS x pT against n) is fine.
DM_TFUNC rvec3 dmFrameCoordinates(rvec3 w, rvec3 pS, rvec3 pT, rvec3 n) {
    rvec3 tn = cross(pT, n);
    rvec3 ns = cross(n, pS);
    rvec3 st = cross(pS, pT);
    real inv = real(1) / dmDot3(pS, tn);
    return rvec3(dmDot3(w, tn) * inv, dmDot3(w, ns) * inv, dmDot3(w, st) * inv);
}

// The world point of voxel-space point p for the ray that entered at voxel-space point o,
// where the base point is `base`: base + a pS + b pT + c n with (a, b, c) the voxel offset
// p - o in texture units and world units along n (the inverse of dmFrameCoordinates and
// dmTangentToVoxel's scaling; locally planar, as the march).
DM_TFUNC rvec3 dmFramePoint(rvec3 base, rvec3 p, rvec3 o, rvec3 pS, rvec3 pT, rvec3 n, rvec3 voxelsPerUnit) {
    rvec3 q = p - o;
    return base + pS * (q.x / voxelsPerUnit.x) + pT * (q.y / voxelsPerUnit.y) + n * (q.z / voxelsPerUnit.z);
}

// The unit world normal of the height field at cell corners h, fraction f, on the frame: the
// cross product of the surface's derivatives along s and t, pS + H_s n and pT + H_t n (H_s the
// height's world slope per texture unit: voxel slope g.x times W / (L / depth)), turned to the
// side of n (a mirrored chart flips the cross product).
DM_TFUNC rvec3 dmFrameNormal(rvec4 h, rvec2 f, rvec3 pS, rvec3 pT, rvec3 n, rvec3 voxelsPerUnit) {
    rvec2 g = dmMesoHeightGradient(h, f);
    rvec3 ds = pS + n * (g.x * (voxelsPerUnit.x / voxelsPerUnit.z));
    rvec3 dt = pT + n * (g.y * (voxelsPerUnit.y / voxelsPerUnit.z));
    rvec3 m = cross(ds, dt);
    if (dmDot3(m, n) < real(0)) {
        m = -m;
    }
    return m * (real(1) / sqrt(dmDot3(m, m)));
}

// The unit world normal of a voxel-space normal nv (a solid's, meso/solid.h) on the frame
// (pS, pT, n): normals take the inverse transpose of the map from voxel to world vectors,
// whose columns are f1 = pS / vpu.x, f2 = pT / vpu.y, f3 = n / vpu.z, i.e. the sum of nv's
// components times the cross products f2 x f3, f3 x f1, f1 x f2, turned by the sign of the
// frame's determinant (a mirrored chart). On the plane pass the axes: (nv.x vpu.x, nv.y vpu.y,
// nv.z vpu.z), unit.
DM_TFUNC rvec3 dmFrameVoxelNormal(rvec3 nv, rvec3 pS, rvec3 pT, rvec3 n, rvec3 voxelsPerUnit) {
    rvec3 f1 = pS * (real(1) / voxelsPerUnit.x);
    rvec3 f2 = pT * (real(1) / voxelsPerUnit.y);
    rvec3 f3 = n * (real(1) / voxelsPerUnit.z);
    rvec3 c23 = dmCross3(f2, f3);
    rvec3 m = (c23 * nv.x + dmCross3(f3, f1) * nv.y) + dmCross3(f1, f2) * nv.z;
    if (dmDot3(f1, c23) < real(0)) {
        m = -m;
    }
    return m * (real(1) / sqrt(dmDot3(m, m)));
}

// The shape of a base (FrameVertex::shape) with its curvature limited to `limit` / slab depth:
// where the base's most convex radius is below depth / limit, K and m are scaled down together
// so that it is depth / limit. The locally quadric shell is an offset of a ball of that radius;
// where the slab is deeper than a fair share of the radius (a thin muzzle or ear under a thick
// slab) the ball leaves out surface that the true base still has along the ray's path, and a
// ray bent by it leaves too early: a hole inside the object's outline. The slab's depth in world
// units is L / vpu.z.
DM_TFUNC rvec4 dmShellLimit(rvec4 shape, rvec3 voxelsPerUnit, real L, real limit) {
    real k = -shape.w * (L / voxelsPerUnit.z); // the most convex curvature times the depth
    return k > limit ? shape * (limit / k) : shape;
}

// A base's shape (FrameVertex::shape) in voxels: (K_xx, K_xy, K_yy, m) of dmShellExit's quadric,
// K_xx = shape.x vpu.z / vpu.x^2, K_xy = shape.y vpu.z / (vpu.x vpu.y), K_yy = shape.z vpu.z /
// vpu.y^2, m = shape.w / vpu.z.
DM_TFUNC rvec4 dmShellVoxels(rvec4 shape, rvec3 voxelsPerUnit) {
    return rvec4(shape.x * (voxelsPerUnit.z / (voxelsPerUnit.x * voxelsPerUnit.x)),
                 shape.y * (voxelsPerUnit.z / (voxelsPerUnit.x * voxelsPerUnit.y)),
                 shape.z * (voxelsPerUnit.z / (voxelsPerUnit.y * voxelsPerUnit.y)), shape.w / voxelsPerUnit.z);
}

// The coefficient of t^2 in the quadric k (dmShellVoxels) along direction d:
// (1/2) (d_h^T K d_h + m d.z^2).
DM_TFUNC real dmShellAlong(rvec3 d, rvec4 k) {
    rvec2 kd = rvec2(k.x * d.x + k.y * d.y, k.y * d.x + k.z * d.y);
    return real(0.5) * ((d.x * kd.x + d.y * kd.y) + k.w * (d.z * d.z));
}

// The bend of the ray p + t d in the shell's own coordinates (dmShellExit's quadric, below): the
// coefficient a of t^2 in F along the ray, voxels^-1. In the slab's coordinates, where the top
// lies at z = L everywhere, the straight world ray from the entry o is the curve dmBentPoint
// (meso.h: F = a t^2 - d.z t taken to the depth; with no convex curvature the parabola
// o + t d - a t^2 z): a < 0 along a convex direction (the ray rises back to the top and leaves),
// a > 0 along a concave one.
DM_TFUNC real dmShellBend(rvec3 d, rvec4 shape, rvec3 voxelsPerUnit) {
    return dmShellAlong(d, dmShellVoxels(shape, voxelsPerUnit));
}

// Where the ray p + t d (voxel space, t >= 0) leaves a curved base's shell through its top: the
// silhouette of the detail itself. The march itself stays locally planar (Donnelly §8.3.1); the
// shell's top is modelled around the entry point o by a quadric with the base's second
// fundamental form: with e = (x, y) - (o.x, o.y) the horizontal offset and z' = z - top the
// height over the entry's tangent plane (voxels), the top is where
//     F = (1/2) e^T K e + (1/2) m z'^2 - z' = 0,   inside (below the top) where F > 0.
// K is `shape`.xyz (n . P_ss, n . P_st, n . P_tt: world units per squared texture unit,
// FrameVertex::shape) and m is shape.w (the most convex principal curvature, <= 0, 1 / world
// units), both in voxels (dmShellVoxels). Negative along a convex direction: there the top
// falls away below the tangent plane. The z'^2 term makes the quadric the exact shell of a
// sphere and of a cylinder (both principal radii, or the one curved direction, meet the
// vertical); without it (m = 0) the shell is the osculating paraboloid. Along the ray
// F = c + b t + a t^2; the answer is its least root t >= 0 where F falls (F' <= 0), from the
// stable pair q / a and c / q; real(-1) where there is none (flat or concave along the ray,
// or a top that curls over it). A start above the top counts as on it (c >= 0).
DM_TFUNC real dmShellExit(rvec3 p, rvec3 d, rvec3 o, rvec4 shape, rvec3 voxelsPerUnit, real top) {
    rvec4 k = dmShellVoxels(shape, voxelsPerUnit);
    real ex = p.x - o.x;
    real ey = p.y - o.y;
    real zh = min(p.z - top, real(0));
    rvec2 ke = rvec2(k.x * ex + k.y * ey, k.y * ex + k.z * ey);
    real c = max(real(0.5) * ((ex * ke.x + ey * ke.y) + k.w * (zh * zh)) - zh, real(0));
    real b = ((d.x * ke.x + d.y * ke.y) + k.w * (zh * d.z)) - d.z;
    real a = dmShellAlong(d, k);
    real disc = b * b - real(4) * a * c;
    real best = real(-1);
    if (disc >= real(0)) {
        real s = sqrt(disc);
        real q = b < real(0) ? real(-0.5) * (b - s) : real(-0.5) * (b + s);
        if (a != real(0)) {
            real r = q / a;
            if (r >= real(0) && real(2) * a * r + b <= real(0)) {
                best = r;
            }
        }
        if (q != real(0)) {
            real r = c / q;
            if (r >= real(0) && real(2) * a * r + b <= real(0) && (best < real(0) || r < best)) {
                best = r;
            }
        }
    }
    return best;
}

// The tangent-space normal that a normal map's texel c (RGBA in [0, 1]) holds: x = 2 r - 1
// along +s, y = 2 g - 1 along greenT t (greenT -1: green points to the image's top, t = 0, as
// OpenGL and glTF write normal maps; +1: to its bottom, as DirectX), z = 2 b - 1 along the
// surface normal; x and y scaled by `scale` (glTF's normalTexture.scale), then unit length
// (a texel of length 0 is the unperturbed normal, (0, 0, 1)).
DM_TFUNC rvec3 dmNormalMapTangent(rvec4 c, real scale, real greenT) {
    rvec3 n = rvec3((c.x * real(2) - real(1)) * scale, (c.y * real(2) - real(1)) * (scale * greenT), c.z * real(2) - real(1));
    real l = dmDot3(n, n);
    return l > real(0) ? n * (real(1) / sqrt(l)) : rvec3(real(0), real(0), real(1));
}

// The world normal of tangent-space normal nt on a base's frame (pS, pT, n): x along pS, y
// along pT and z along n, each of unit length (MikkTSpace's rule with the frame's own
// directions), then unit length. On the plane z = 0 (pS, pT, n the axes) it is nt itself.
DM_TFUNC rvec3 dmFrameTangentNormal(rvec3 nt, rvec3 pS, rvec3 pT, rvec3 n) {
    rvec3 w = pS * (nt.x / sqrt(dmDot3(pS, pS))) + pT * (nt.y / sqrt(dmDot3(pT, pT))) + n * (nt.z / sqrt(dmDot3(n, n)));
    return w * (real(1) / sqrt(dmDot3(w, w)));
}

// Albedo of a checker of `period` voxels (1 and 0.55), so the parallax is visible; a period
// <= 0 is no checker (albedo 1).
DM_TFUNC real dmMesoChecker(rvec2 p, real period) {
    if (!(period > real(0))) {
        return real(1);
    }
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
