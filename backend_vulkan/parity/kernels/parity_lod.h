#pragma once
// Parity dispatch for the level-of-detail kernels (float only in GLSL: they use log2, exp2
// and sqrt, and GLSL has log2 and exp2 for float only). Same argument and result packing as
// parity_tile.h; the kernel numbers continue its list (parity.h).
#include "dispmap/kernels/lod.h"
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin
DM_TFUNC void dmParityLod(int kernel, rvec4 a, rvec4 b, ivec4 n, DM_OUT(rvec4) r, DM_OUT(ivec4) o) {
    r = rvec4(real(0));
    o = ivec4(0);
    if (kernel == 32) {
        r.x = dmTessFactorDistance(rvec3(a.x, a.y, a.z), rvec3(a.w, b.x, b.y), b.z);
    } else if (kernel == 33) {
        r.x = dmTessAreaTerm(rvec2(a.x, a.y), rvec2(a.z, a.w));
    } else if (kernel == 34) {
        r.x = dmTessFactorArea(a.x, a.y);
    } else if (kernel == 35) {
        r.x = dmTessFactorEdge(a.x, a.y);
    } else if (kernel == 36) {
        r.x = dmClampTessFactor(a.x, a.y);
    } else if (kernel == 37) {
        r = dmEdgeTessFactors(a);
    } else if (kernel == 38) {
        rvec2 inner = dmInnerTessFactors(a);
        r = rvec4(inner.x, inner.y, real(0), real(0));
    } else if (kernel == 39) {
        int mFine;
        int mCoarse;
        r.x = dmSelectMips(a.x, a.y, n.x, mFine, mCoarse);
        o = ivec4(mFine, mCoarse, 0, 0);
    } else if (kernel == 40) {
        r.x = dmResolutionFromTessFactor(a.x);
    } else if (kernel == 41) {
        r.x = dmMipLevelTexelRatio(a.x, a.y);
    } else if (kernel == 42) {
        r.x = dmVertexResolutionTexelRatio(n.x, a.x);
    }
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
