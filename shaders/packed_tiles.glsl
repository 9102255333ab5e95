// The packed displacement lookup of the renderer, shared by shaders/render and the parity
// shader (shaders/parity_packed.comp): PackedTiles::sampleD1 (tileset.h), gather for gather.
// The includer declares `float texels[]` (the packed texture, row by row) and
// `int packedWidth()` (its width in texels) before including this file; or it defines
// DM_PACKED_TEXEL(x, y), the texel at column x, row y, to read the texture some other way
// (half floats in a storage buffer, a sampled image: shaders/render/common.glsl).
#ifndef DM_PACKED_TEXEL
#define DM_PACKED_TEXEL(x, y) texels[(y) * packedWidth() + (x)]
#endif

// (D, D_u, D_v) of level m of the tile of record r at its (u, v).
vec3 packedLevelD1(uvec4 r, int m, vec2 uv) {
    ivec2 texel;
    vec2 t = dmPackedLocate(r, m, uv, texel);
    mat3 c;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            c[i][j] = DM_PACKED_TEXEL(texel.x + i, texel.y + j);
        }
    }
    return dmTileD1(c, t, dmRecordTileSize(r) >> m);
}

// (D, D_u, D_v) at the tile's (u, v) read at resolution rho: the §4.4 maximum, the two mip
// levels dmSelectMips picks and their blend; weight: the finer level's share.
vec3 packedSampleD1(uvec4 r, vec2 uv, float rho, out float weight) {
    int k = dmTileLog2(dmRecordTileSize(r));
    float maxRes = dmMaxResolution(k, dmUnpackSizeDifferences(r.w), uv);
    int mFine;
    int mCoarse;
    weight = dmSelectMips(rho, maxRes, k, mFine, mCoarse);
    return dmBlendMips(packedLevelD1(r, mCoarse, uv), packedLevelD1(r, mFine, uv), weight);
}
