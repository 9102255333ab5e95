#pragma once
// Displacement tiles: sub-patch location, biquadratic evaluation, the packed layout of a
// tile's mip levels, the 16-byte patch record and the per-corner tile-size differences.
// Source: Nießner & Loop 2013, §4 (tile format), §4.3 (packing), §4.4 (mixed sizes),
// §5.1 (evaluation), §5.4 (patch record).
//
// Conventions (one tile level of size s = 2^k, k >= 1):
//  * the level holds (s+2) x (s+2) coefficients c[a][b], a along u, b along v, a,b = 0..s+1;
//    the outermost ring (a or b equal to 0 or s+1) is the one-texel overlap;
//  * coefficient (a, b) is centred at ((a - 1/2)/s, (b - 1/2)/s) in the face's (u, v);
//  * sub-patch (i, j), i, j = 0..s-1, covers [i/s, (i+1)/s] x [j/s, (j+1)/s] and reads the
//    3 x 3 coefficients a = i..i+2, b = j..j+2 with local parameter t = s*u - i in [0, 1];
//  * u = 1 belongs to sub-patch s-1 (t = 1), so both sides of a tile edge read the two
//    coefficient rows that both tiles hold: D is C0 and C1 across the edge;
//  * derivatives with respect to the face's (u, v) carry the factor s (s^2 for second).
//  This is the paper's map T(u) = u - floor(u) + 1/2 written in coefficient indices: its
//  B-spline knots sit at the sub-patch corners.
#include "dispmap/kernels/bspline.h"
#include "dispmap/kernels/sum.h"
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
// Locates (u, v) in a tile level with s x s sub-patches: writes the sub-patch index (0..s-1
// per axis) and returns the local parameter in [0, 1]^2. (u, v) is clamped into [0, 1]^2.
DM_TFUNC rvec2 dmSubpatch(rvec2 uv, int s, DM_OUT(ivec2) cell) {
    rvec2 x = clamp(uv, rvec2(real(0)), rvec2(real(1))) * real(s);
    cell = min(ivec2(floor(x)), ivec2(s - 1));
    return x - rvec2(cell);
}

// D on one sub-patch: c[i][j] is the coefficient i along u, j along v; t the local parameter.
// The sums are in a fixed order (sum.h) so that C++ and GLSL agree bit for bit.
DM_TFUNC real dmBiquadratic(rmat3 c, rvec2 t) {
    return dmDot3(dmMulMV3(c, dmBSpline2(t.x)), dmBSpline2(t.y));
}

// D and its first derivatives with respect to the local parameter: (D, dD/dtu, dD/dtv).
DM_TFUNC rvec3 dmBiquadraticD1(rmat3 c, rvec2 t) {
    rvec3 bu = dmBSpline2(t.x);
    rvec3 bv = dmBSpline2(t.y);
    rvec3 cu = dmMulMV3(c, bu);
    return rvec3(dmDot3(cu, bv), dmDot3(dmMulMV3(c, dmBSpline2D1(t.x)), bv), dmDot3(cu, dmBSpline2D1(t.y)));
}

// Second derivatives with respect to the local parameter: (d2D/dtu2, d2D/dtu dtv, d2D/dtv2).
DM_TFUNC rvec3 dmBiquadraticD2(rmat3 c, rvec2 t) {
    rmat3 bu = dmBSpline2Derivs(t.x);
    rmat3 bv = dmBSpline2Derivs(t.y);
    return rvec3(dmDot3(dmMulMV3(c, bu[2]), bv[0]), dmDot3(dmMulMV3(c, bu[1]), bv[1]),
                 dmDot3(dmMulMV3(c, bu[0]), bv[2]));
}

// (D, D_u, D_v) with respect to the face's (u, v) on a level of size s: dmBiquadraticD1 with
// the local derivatives scaled by s (t = s*u - i).
DM_TFUNC rvec3 dmTileD1(rmat3 c, rvec2 t, int s) {
    rvec3 d = dmBiquadraticD1(c, t);
    return rvec3(d.x, d.y * real(s), d.z * real(s));
}

// Blends (D, D_u, D_v) of two mip levels with the weight of the finer one (dmSelectMips):
// exactly `coarse` at w = 0 and exactly `fine` at w = 1. Written out rather than with mix(),
// whose rounding GLSL leaves to the implementation.
DM_TFUNC rvec3 dmBlendMips(rvec3 coarse, rvec3 fine, real w) {
    return coarse * (real(1) - w) + fine * w;
}

// Bilinear interpolation of four corner values: corner 0 at (0,0), 1 at (1,0), 2 at (1,1),
// 3 at (0,1), the corner order of OpenSubdiv's quads and Ptex faces. On an edge the result
// depends on that edge's two corners only (the other weights are exactly zero).
DM_TFUNC real dmBilerp(rvec4 c, rvec2 uv) {
    real a = real(1) - uv.x;
    real b = real(1) - uv.y;
    return (a * b) * c.x + (uv.x * b) * c.y + (uv.x * uv.y) * c.z + (a * uv.y) * c.w;
}

// Texel offset of mip level m (0 = finest, size s >> m) inside the packed footprint of a tile
// with s = 2^k. Level 0 sits at (0, 0); levels 1..k-1 are stacked in one column to its
// right, each (s >> m) + 2 texels square.
DM_FUNC ivec2 dmMipOffset(int k, int m) {
    int s = 1 << k;
    if (m == 0) {
        return ivec2(0, 0);
    }
    return ivec2(s + 2, s - (s >> (m - 1)) + 2 * (m - 1));
}

// Width and height in texels of the packed footprint of a tile with s = 2^k, levels
// 0..k-1 (the coarsest level has s = 2, so that every level has distinct corner
// coefficients for the constraint at extraordinary vertices).
DM_FUNC ivec2 dmTileFootprint(int k) {
    int s = 1 << k;
    if (k == 1) {
        return ivec2(4, 4);
    }
    return ivec2(s + 2 + (s >> 1) + 2, max(s + 2, s + 2 * k - 4));
}

// log2 of a tile size s = 2^k, 1 <= k <= 15 (the record stores s, as the paper's struct does).
DM_FUNC int dmTileLog2(int s) {
    int k = 0;
    for (int j = 1; j <= 15; ++j) {
        if ((1 << j) == s) {
            k = j;
        }
    }
    return k;
}

// The 16-byte patch record of §5.4, read as four little-endian 32-bit words:
//   x = globalTextureOffsetXY, y = localDomainOffsetXY, z = tileSize | rotation << 16,
//   w = tileSizeDifferences[0..3], corner i in bits 8i..8i+7.
DM_FUNC ivec2 dmRecordTextureOffset(uvec4 r) {
    return ivec2(int(r.x & 0xFFFFu), int(r.x >> 16u));
}
DM_FUNC ivec2 dmRecordLocalOffset(uvec4 r) {
    return ivec2(int(r.y & 0xFFFFu), int(r.y >> 16u));
}
DM_FUNC int dmRecordTileSize(uvec4 r) {
    return int(r.z & 0xFFFFu);
}
DM_FUNC int dmRecordRotation(uvec4 r) {
    return int(r.z >> 16u);
}
DM_FUNC ivec4 dmUnpackSizeDifferences(uint w) {
    return ivec4(int(w & 0xFFu), int((w >> 8u) & 0xFFu), int((w >> 16u) & 0xFFu), int(w >> 24u));
}
DM_FUNC uint dmPackSizeDifferences(ivec4 d) {
    return uint(d.x & 0xFF) | (uint(d.y & 0xFF) << 8u) | (uint(d.z & 0xFF) << 16u) | (uint(d.w & 0xFF) << 24u);
}

// log2 of the finest level size that may be read at (u, v) of a tile with s = 2^k (§4.4):
// k minus the bilinearly interpolated per-corner differences. A corner's difference is k
// minus the smallest k of the tiles around that corner's vertex, so every tile around a
// vertex, and both tiles along an edge, get the same value there.
DM_TFUNC real dmMaxResolution(int k, ivec4 diffs, rvec2 uv) {
    return real(k) - dmBilerp(rvec4(diffs), uv);
}

// Locates (u, v) of the tile of record r in its level m in the packed texture: writes the
// texel of the first coefficient of the 3 x 3 block to read (coefficient (i, j) of the block
// is at texel + (i, j), i along u, texture x) and returns the local parameter t. With the
// block gathered into c[i][j], dmTileD1(c, t, s >> m) is (D, D_u, D_v) at (u, v).
DM_TFUNC rvec2 dmPackedLocate(uvec4 r, int m, rvec2 uv, DM_OUT(ivec2) texel) {
    int s = dmRecordTileSize(r);
    ivec2 cell;
    rvec2 t = dmSubpatch(uv, s >> m, cell);
    texel = dmRecordTextureOffset(r) + dmMipOffset(dmTileLog2(s), m) + cell;
    return t;
}

// Maps a patch's (u, v) into its tile's (u, v) (§5.4): the patch covers the square of side
// 2^-depth at localOffset * 2^-depth (0 <= depth <= 30; the division by 2^depth is exact at
// both precisions, unlike exp2, which GLSL has for float only), turned by `rotation` quarter turns (counter-clockwise
// about the patch centre: rotation 1 maps (u, v) to (1 - v, u)).
DM_TFUNC rvec2 dmPatchToTile(rvec2 uv, ivec2 localOffset, int depth, int rotation) {
    rvec2 r = uv;
    if (rotation == 1) {
        r = rvec2(real(1) - uv.y, uv.x);
    } else if (rotation == 2) {
        r = rvec2(real(1) - uv.x, real(1) - uv.y);
    } else if (rotation == 3) {
        r = rvec2(uv.y, real(1) - uv.x);
    }
    return (rvec2(localOffset) + r) / real(1 << depth);
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
