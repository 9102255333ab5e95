#pragma once
// Level of detail: tessellation factors per base vertex, per edge and inner (Nießner & Loop
// 2013, §6.1), mip selection from the interpolated factor with blending between levels
// (§6.2), and the mip rule of the texel-ratio rule (M = log2(L/T) + 1), all as per-vertex values that
// every face around a vertex reproduces exactly.
//
// Resolution: we name a tile level by the log2 of its size, rho; level m of a tile with
// s = 2^k has rho = k - m. A factor TF puts TF segments along an edge, and §6.2 reads the
// level with rho = log2 TF (blending floor and ceil); the texel-ratio rule wants at most half a texel per
// segment, rho = log2 TF - 1. Both are clamped to [1, dmMaxResolution].
#include "dispmap/kernels/tile.h"
// Dependencies first: the prelude must come last, after their prelude_end.h.
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin
// Distance based factor of a base vertex v seen from eye: c / |eye - v|. (The paper prints
// c * |eye - v|, which would refine what is far away; the factor must fall with distance.)
// The distance is bounded below by 1e-6 of the scene scale c so that a vertex at the eye
// gets a large finite factor, never Inf.
DM_TFUNC real dmTessFactorDistance(rvec3 eye, rvec3 v, real c) {
    return c / max(length(eye - v), real(1e-6) * abs(c));
}

// One term of the screen-space area factor: |e_i x e_{i+1}| for two consecutive screen-space
// edge vectors (in pixels) of the vertex's one-ring. The caller sums the terms over the ring.
DM_TFUNC real dmTessAreaTerm(rvec2 e0, rvec2 e1) {
    return abs(e0.x * e1.y - e0.y * e1.x);
}

// Screen-space area factor from the summed terms: c * sqrt(sum |e_i x e_{i+1}|).
DM_TFUNC real dmTessFactorArea(real sumOfTerms, real c) {
    return c * sqrt(max(sumOfTerms, real(0)));
}

// Screen-space edge length factor from the longest one-ring edge (in pixels): c * max |e_i|.
DM_TFUNC real dmTessFactorEdge(real longestEdge, real c) {
    return c * longestEdge;
}

// Clamps a factor into [1, maxFactor] (the device's maxTessellationGenerationLevel).
DM_TFUNC real dmClampTessFactor(real tf, real maxFactor) {
    return clamp(tf, real(1), maxFactor);
}

// Edge factors of a quad from its corner factors: edge i runs from corner i to corner i+1
// and takes the larger of the two, so both faces of an edge compute the same factor.
DM_TFUNC rvec4 dmEdgeTessFactors(rvec4 corner) {
    return max(corner, rvec4(corner.y, corner.z, corner.w, corner.x));
}

// Inner factors from edge factors: along u the larger of edges 0 and 2, along v of 1 and 3.
DM_TFUNC rvec2 dmInnerTessFactors(rvec4 edge) {
    return rvec2(max(edge.x, edge.z), max(edge.y, edge.w));
}

// Selects the two mip levels to blend for a resolution rho (log2 of the wanted level size),
// clamped to [1, maxRes] and maxRes to [1, k]. Writes the finer and the coarser mip index
// (0 = finest) and returns the weight of the finer one:
// D = mix(D[mCoarse], D[mFine], weight). An integral rho gives weight 0: one level only.
DM_TFUNC real dmSelectMips(real rho, real maxRes, int k, DM_OUT(int) mFine, DM_OUT(int) mCoarse) {
    real top = clamp(maxRes, real(1), real(k));
    real r = clamp(rho, real(1), top);
    real lo = floor(r);
    int rLo = int(lo);
    mCoarse = k - rLo;
    mFine = k - min(rLo + 1, k);
    return r - lo;
}

// §6.2: the resolution read for a bilinearly interpolated tessellation factor, log2 TF.
DM_TFUNC real dmResolutionFromTessFactor(real tf) {
    return log2(max(tf, real(1)));
}

// Texel ratio: the mip level M = log2(L / T) + 1 of an edge L texels long with factor T, which
// leaves at most half a texel per segment; never below 0 (the finest level).
DM_TFUNC real dmMipLevelTexelRatio(real texels, real tf) {
    return max(log2(texels / max(tf, real(1))) + real(1), real(0));
}

// Texel ratio per base vertex: with L = 2^kMin texels along the vertex's edges (kMin = the
// smallest tile size around the vertex, the finest level every tile there has), the level
// M becomes the resolution kMin - M. A per-vertex value, interpolated with dmBilerp, gives
// every face around a vertex, and both faces of an edge, the same level there.
DM_TFUNC real dmVertexResolutionTexelRatio(int kMin, real tf) {
    return real(kMin) - dmMipLevelTexelRatio(exp2(real(kMin)), tf);
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
