#pragma once
// Parity dispatch for the base-surface patch kernels (kernels/patch.h): one function that runs
// kernel number `kernel` on one (PatchParam, control-point count, face (u, v)) and packs its
// results. Written in the kernel subset and mirrored into GLSL by dispmap_glslgen, like
// parity_tile.h, so the CPU and the compute shader marshal with the same text.
//
// Arguments: param = uvec2(field0, field1) of a Far::PatchParam, cvCount (16 or 20), uv. Results:
// r (120 reals), o (4 ints); everything a kernel does not write is 0.
//   0  dmPatchBasis2: r[20 k + i] = w, wu, wv, wuu, wuv, wvv (k = 0..5) of point i
//   1  dmPatchBasis1: r[20 k + i] = w, wu, wv (k = 0..2)
//   2  dmQuadTreeStep, 10 steps from uv: r[2 j], r[2 j + 1] = uv after step j; o.x the
//      quadrants, step j in bits 2j..2j+1
//   3  PatchParam decoding, dmPatchLocal, dmEndCapCornerWeights: r[0..1] the local parameter,
//      r[2..5] the corner weights; o = (depth | NonQuadRoot << 4 | regular << 5 | boundary << 8,
//      U | V << 16, face id, dmPatchDomainLevel)
#include "dispmap/kernels/patch.h"
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
DM_TFUNC void dmParityPatch(int kernel, uvec2 param, int cvCount, rvec2 uv, DM_OUT_ARRAY(real) r[120], DM_OUT(ivec4) o) {
    for (int i = 0; i < 120; ++i) {
        r[i] = real(0);
    }
    o = ivec4(0);
    real w[20];
    real wu[20];
    real wv[20];
    real wuu[20];
    real wuv[20];
    real wvv[20];
    if (kernel == 0) {
        dmPatchBasis2(param, cvCount, uv, w, wu, wv, wuu, wuv, wvv);
        for (int i = 0; i < 20; ++i) {
            r[i] = w[i];
            r[20 + i] = wu[i];
            r[40 + i] = wv[i];
            r[60 + i] = wuu[i];
            r[80 + i] = wuv[i];
            r[100 + i] = wvv[i];
        }
    } else if (kernel == 1) {
        dmPatchBasis1(param, cvCount, uv, w, wu, wv);
        for (int i = 0; i < 20; ++i) {
            r[i] = w[i];
            r[20 + i] = wu[i];
            r[40 + i] = wv[i];
        }
    } else if (kernel == 2) {
        rvec2 q = uv;
        int bits = 0;
        for (int j = 0; j < 10; ++j) {
            bits = bits | (dmQuadTreeStep(q) << (2 * j));
            r[2 * j] = q.x;
            r[2 * j + 1] = q.y;
        }
        o.x = bits;
    } else if (kernel == 3) {
        rvec2 l = dmPatchLocal(param, uv);
        rvec4 c = dmEndCapCornerWeights(param, uv);
        r[0] = l.x;
        r[1] = l.y;
        r[2] = c.x;
        r[3] = c.y;
        r[4] = c.z;
        r[5] = c.w;
        int flags = dmPatchDepth(param);
        if (dmPatchNonQuadRoot(param)) {
            flags = flags | 16;
        }
        if (dmPatchRegular(param)) {
            flags = flags | 32;
        }
        ivec2 off = dmPatchOffset(param);
        o = ivec4(flags | (dmPatchBoundary(param) << 8), off.x | (off.y << 16), dmPatchFaceId(param),
                  dmPatchDomainLevel(param));
    }
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
