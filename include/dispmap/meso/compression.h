#pragma once
// CompressedDdm: the two-level lookup grid + atlas of blocks of a directional distance map
// (Mehra & Kumar §4, Appendix A). GLM only.
#include "dispmap/meso/ddm.h"

namespace dispmap {

/// The two-level compressed DDM (Mehra & Kumar §4, Algorithms A.1 / A.2): per cone a lookup
/// grid of block x block x block blocks; a block holding both 0 and non-zero values (a surface
/// may pass through it) is stored whole in the atlas and its grid word holds its atlas index
/// with bit 31 set; a block of zeros only (inside the solid) keeps 0, and any other block only
/// its minimum (the word holds the float's bits), which is again conservative, unless its
/// values spread by more than compressDdm's maxSpread: then it is stored whole too (a block
/// whose minimum sits far below most of its values would make the march take short steps
/// there). Atlas voxels and zero blocks read back bit for bit; the rest read their block's
/// minimum.
struct CompressedDdm {
    int width = 0, height = 0, layers = 0, block = 4;
    int gx = 0, gy = 0, gz = 0; ///< grid size in blocks
    ConeSet cones;
    std::vector<std::uint32_t> grid; ///< [cone][bz][by][bx]
    std::vector<float> atlas;        ///< blocks of block^3 values, x fastest

    std::size_t gridIndex(int c, int bx, int by, int bz) const {
        return ((static_cast<std::size_t>(c) * static_cast<std::size_t>(gz) + static_cast<std::size_t>(bz)) *
                    static_cast<std::size_t>(gy) +
                static_cast<std::size_t>(by)) *
                   static_cast<std::size_t>(gx) +
               static_cast<std::size_t>(bx);
    }
    /// Appendix A.2 on voxel (i, j, k), i and j wrapped; k in [0, layers).
    float lookup(int c, int i, int j, int k) const {
        i = detail::wrapIndex(i, width);
        j = detail::wrapIndex(j, height);
        int atlasIndex = -1;
        const float d = kern::dmGridWordDistance(grid[gridIndex(c, i / block, j / block, k / block)], atlasIndex);
        if (atlasIndex < 0) return d;
        const int b = block;
        return atlas[static_cast<std::size_t>(atlasIndex) * static_cast<std::size_t>(b * b * b) +
                     static_cast<std::size_t>(((k % b) * b + j % b) * b + i % b)];
    }
    std::size_t uncompressedBytes() const {
        return static_cast<std::size_t>(cones.count()) * static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
               static_cast<std::size_t>(layers) * sizeof(float);
    }
    std::size_t bytes() const { return grid.size() * sizeof(std::uint32_t) + atlas.size() * sizeof(float); }
    double ratio() const { return static_cast<double>(uncompressedBytes()) / static_cast<double>(std::max<std::size_t>(bytes(), 1)); }
    std::size_t atlasBlocks() const { return atlas.size() / static_cast<std::size_t>(block * block * block); }
};

/// The spread (largest minus smallest value, in voxels) above which a block of free space is
/// stored whole (compressDdm's default; `dispmap meso --table` prints the memory and the
/// iterations each choice gives).
inline constexpr float kDefaultCompressionSpread = 2.0f;

/// Compresses `m` in blocks of `block`^3 voxels (block divides the sizes). `maxSpread` >= 0
/// (voxels; +Inf: only blocks that hold a 0 and a non-zero value go to the atlas, the paper's
/// rule). ArgumentError otherwise.
inline CompressedDdm compressDdm(const DirectionalDistanceMap& m, int block = 4, float maxSpread = kDefaultCompressionSpread) {
    if (block < 1 || block > 32 || m.width % block || m.height % block || m.layers % block)
        throw ArgumentError("compressDdm: block " + std::to_string(block) + " must divide " + std::to_string(m.width) + " x " +
                            std::to_string(m.height) + " x " + std::to_string(m.layers));
    if (!(maxSpread >= 0.0f))
        throw ArgumentError("compressDdm: the largest spread of a block stored as one value must be >= 0 voxels (+Inf: the paper's rule)");
    CompressedDdm c;
    c.width = m.width;
    c.height = m.height;
    c.layers = m.layers;
    c.block = block;
    c.cones = m.cones;
    c.gx = m.width / block;
    c.gy = m.height / block;
    c.gz = m.layers / block;
    c.grid.resize(static_cast<std::size_t>(m.cones.count()) * static_cast<std::size_t>(c.gx) * static_cast<std::size_t>(c.gy) *
                  static_cast<std::size_t>(c.gz));
    const std::size_t atlasMax = (std::size_t(1) << 31) - 1;
    for (int cone = 0; cone < m.cones.count(); ++cone)
        for (int bz = 0; bz < c.gz; ++bz)
            for (int by = 0; by < c.gy; ++by)
                for (int bx = 0; bx < c.gx; ++bx) {
                    float lo = std::numeric_limits<float>::infinity();
                    for (int k = 0; k < block; ++k)
                        for (int j = 0; j < block; ++j)
                            for (int i = 0; i < block; ++i)
                                lo = std::min(lo, m.at(cone, bx * block + i, by * block + j, bz * block + k));
                    float hi = 0.0f;
                    for (int k = 0; k < block; ++k)
                        for (int j = 0; j < block; ++j)
                            for (int i = 0; i < block; ++i)
                                hi = std::max(hi, m.at(cone, bx * block + i, by * block + j, bz * block + k));
                    std::uint32_t word;
                    if (hi == 0.0f || (lo > 0.0f && hi - lo <= maxSpread)) { // all 0 (inside the solid), or even free space: one value
                        std::memcpy(&word, &lo, sizeof word);
                    } else {
                        const std::size_t index = c.atlasBlocks();
                        if (index > atlasMax) throw ArgumentError("compressDdm: more than 2^31 atlas blocks");
                        for (int k = 0; k < block; ++k)
                            for (int j = 0; j < block; ++j)
                                for (int i = 0; i < block; ++i)
                                    c.atlas.push_back(m.at(cone, bx * block + i, by * block + j, bz * block + k));
                        word = 0x80000000u | static_cast<std::uint32_t>(index);
                    }
                    c.grid[c.gridIndex(cone, bx, by, bz)] = word;
                }
    return c;
}

} // namespace dispmap
