#pragma once
// Parity dispatch for the precision-generic kernels (B-spline basis, tile evaluation and
// addressing, patch record): one function that runs kernel number `kernel` on a packed
// argument list. It is itself written in the kernel subset and mirrored into GLSL by
// dispmap_glslgen, so the CPU and the compute shader unpack arguments and pack results with
// the same text; a marshalling slip cannot hide a kernel difference.
//
// Arguments: a, b, c (12 reals), n (4 ints). Results: r, q, p (12 reals), o (4 ints). Every
// result not written by a kernel is 0. The kernel numbers are listed in parity.h.
#include "dispmap/kernels/tile.h"
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
DM_TFUNC rmat3 dmParityMatrix(rvec4 a, rvec4 b, rvec4 c) {
    return rmat3(rvec3(a.x, a.y, a.z), rvec3(a.w, b.x, b.y), rvec3(b.z, b.w, c.x));
}

DM_TFUNC void dmParityTile(int kernel, rvec4 a, rvec4 b, rvec4 c, ivec4 n, DM_OUT(rvec4) r, DM_OUT(rvec4) q,
                           DM_OUT(rvec4) p, DM_OUT(ivec4) o) {
    r = rvec4(real(0));
    q = rvec4(real(0));
    p = rvec4(real(0));
    o = ivec4(0);
    rvec2 uv = rvec2(a.x, a.y);
    if (kernel == 0) {
        r = rvec4(dmBSpline2(a.x), real(0));
    } else if (kernel == 1) {
        r = rvec4(dmBSpline2D1(a.x), real(0));
    } else if (kernel == 2) {
        rmat3 m = dmBSpline2Derivs(a.x);
        r = rvec4(m[0], real(0));
        q = rvec4(m[1], real(0));
        p = rvec4(m[2], real(0));
    } else if (kernel == 3) {
        ivec2 cell;
        rvec2 t = dmSubpatch(uv, n.x, cell);
        r = rvec4(t.x, t.y, real(0), real(0));
        o = ivec4(cell.x, cell.y, 0, 0);
    } else if (kernel == 4) {
        r.x = dmBiquadratic(dmParityMatrix(a, b, c), rvec2(c.y, c.z));
    } else if (kernel == 5) {
        r = rvec4(dmBiquadraticD1(dmParityMatrix(a, b, c), rvec2(c.y, c.z)), real(0));
    } else if (kernel == 6) {
        r = rvec4(dmBiquadraticD2(dmParityMatrix(a, b, c), rvec2(c.y, c.z)), real(0));
    } else if (kernel == 7) {
        r = rvec4(dmTileD1(dmParityMatrix(a, b, c), rvec2(c.y, c.z), n.x), real(0));
    } else if (kernel == 8) {
        r = rvec4(dmBlendMips(rvec3(a.x, a.y, a.z), rvec3(a.w, b.x, b.y), b.z), real(0));
    } else if (kernel == 9) {
        r.x = dmBilerp(b, uv);
    } else if (kernel == 10) {
        o = ivec4(dmMipOffset(n.x, n.y), dmTileFootprint(n.x));
    } else if (kernel == 11) {
        o.x = dmTileLog2(n.x);
    } else if (kernel == 12) {
        uvec4 w = uvec4(n);
        o = ivec4(dmRecordTextureOffset(w), dmRecordLocalOffset(w));
    } else if (kernel == 13) {
        uvec4 w = uvec4(n);
        o = ivec4(dmRecordTileSize(w), dmRecordRotation(w), dmUnpackSizeDifferences(w.w).x,
                  dmUnpackSizeDifferences(w.w).w);
    } else if (kernel == 14) {
        o = dmUnpackSizeDifferences(uint(n.x));
    } else if (kernel == 15) {
        o.x = int(dmPackSizeDifferences(n));
    } else if (kernel == 16) {
        r.x = dmMaxResolution(n.x, dmUnpackSizeDifferences(uint(n.y)), uv);
    } else if (kernel == 17) {
        ivec2 texel;
        rvec2 t = dmPackedLocate(uvec4(n), int(a.z), uv, texel);
        r = rvec4(t.x, t.y, real(0), real(0));
        o = ivec4(texel.x, texel.y, 0, 0);
    } else if (kernel == 18) {
        r = rvec4(dmPatchToTile(uv, ivec2(n.x, n.y), n.z, n.w), real(0), real(0));
    }
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
