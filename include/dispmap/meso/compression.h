#pragma once
// CompressedDdm: the two-level lookup grid + atlas of blocks of a directional distance map
// (Mehra & Kumar §4, Appendix A). GLM only.
#include <cmath>
#include <cstring>

#include "dispmap/meso/ddm.h"

namespace dispmap {

/// The two-level compressed DDM (Mehra & Kumar §4, Algorithms A.1 / A.2): per cone a lookup
/// grid of block x block x block blocks (the word's kinds: kern::dmGridWordDistance). A block
/// of zeros only (inside the solid) keeps 0; a block of free space keeps its minimum (the word
/// holds the float's bits), which is again conservative, when its values spread by at most
/// compressDdm's maxSpread (the paper keeps every free block so); any other block the plane
/// below its values (kern::dmPlaneBlockDistance, four floats in `planes`) when no voxel reads
/// more than maxSpread / 2 below its value and exactly its zeros read 0 (a surface may pass
/// only there: a block over a floor is such a ramp); else it is stored whole in the atlas, as
/// the paper stores every block that holds a 0 and a non-zero value (a block whose bound sits
/// far below most of its values would make the march take short steps there). Atlas voxels
/// and zero blocks read back bit for bit; the rest read a lower bound within maxSpread of their
/// value.
/// On the GPU the atlas buffer holds `atlas` and then `planes` (a plane word holds the offset
/// of its record in that buffer, atlas.size() and up).
struct CompressedDdm {
    int width = 0, height = 0, layers = 0, block = 4;
    int gx = 0, gy = 0, gz = 0; ///< grid size in blocks
    ConeSet cones;
    std::vector<std::uint32_t> grid; ///< [cone][bz][by][bx]
    std::vector<float> atlas;        ///< blocks of block^3 values, x fastest
    std::vector<float> planes;       ///< plane blocks' records (a0, gx, gy, gz), read at their word's offset - atlas.size()

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
        int atlasIndex = -1, kind = 0;
        const float d = kern::dmGridWordDistance(grid[gridIndex(c, i / block, j / block, k / block)], atlasIndex, kind);
        if (kind == 0) return d;
        const int b = block;
        if (kind == 2) {
            const float* p = planes.data() + (static_cast<std::size_t>(atlasIndex) - atlas.size());
            return kern::dmPlaneBlockDistance(p[0], p[1], p[2], p[3], glm::ivec3(i % b, j % b, k % b));
        }
        return atlas[static_cast<std::size_t>(atlasIndex) * static_cast<std::size_t>(b * b * b) +
                     static_cast<std::size_t>(((k % b) * b + j % b) * b + i % b)];
    }
    /// Whether every grid word names a block or a plane record that exists (what a loader checks).
    bool wordsValid() const {
        for (std::uint32_t w : grid) {
            int index = -1, kind = 0;
            const float d = kern::dmGridWordDistance(w, index, kind);
            const auto at = static_cast<std::size_t>(index);
            if (kind == 0 ? !(d >= 0 && std::isfinite(d))
                          : kind == 1 ? at >= atlasBlocks() : at < atlas.size() || (at - atlas.size()) % 4 != 0 || at - atlas.size() + 4 > planes.size())
                return false;
        }
        return true;
    }
    std::size_t uncompressedBytes() const {
        return static_cast<std::size_t>(cones.count()) * static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
               static_cast<std::size_t>(layers) * sizeof(float);
    }
    std::size_t bytes() const { return grid.size() * sizeof(std::uint32_t) + (atlas.size() + planes.size()) * sizeof(float); }
    double ratio() const { return static_cast<double>(uncompressedBytes()) / static_cast<double>(std::max<std::size_t>(bytes(), 1)); }
    std::size_t atlasBlocks() const { return atlas.size() / static_cast<std::size_t>(block * block * block); }
    std::size_t planeBlocks() const { return planes.size() / 4; }
};

/// The spread (largest minus smallest value, in voxels) above which a block of free space is
/// stored whole (compressDdm's default; `dispmap meso --table` prints the memory and the
/// iterations each choice gives).
inline constexpr float kDefaultCompressionSpread = 2.0f;

namespace detail {
// The plane below a block (values v >= 0, x fastest) that reads each voxel at most maxDeficit
// below its value, and 0 exactly where the value is 0, through kern::dmPlaneBlockDistance: the
// least-squares slopes (the normal equations of a full grid separate by axis), the offset
// lowered until every voxel reads at most its value in float. False when some voxel would
// read more than maxDeficit below it, or 0 where its value is not (the block is then whole).
inline bool fitPlaneBlock(const std::vector<float>& v, int block, float maxDeficit, glm::vec4& plane) {
    const double mid = 0.5 * (block - 1);
    double sum = 0, sx = 0, sy = 0, sz = 0, s2 = 0;
    for (int k = 0; k < block; ++k)
        for (int j = 0; j < block; ++j)
            for (int i = 0; i < block; ++i) {
                const double d = v[static_cast<std::size_t>((k * block + j) * block + i)];
                sum += d;
                sx += (i - mid) * d;
                sy += (j - mid) * d;
                sz += (k - mid) * d;
            }
    for (int i = 0; i < block; ++i) s2 += (i - mid) * (i - mid);
    const double n = static_cast<double>(v.size()), per = s2 * block * block; // sum of (i - mid)^2 over the block
    if (!(per > 0)) return false; // a block of one voxel
    const glm::dvec3 g(sx / per, sy / per, sz / per);
    plane = glm::vec4(static_cast<float>(sum / n - glm::dot(g, glm::dvec3(mid))), glm::vec3(g));
    // Lower the offset until no voxel reads above its value (a few rounds at most: each takes
    // the largest excess off, and rounding can leave an ULP).
    for (int round = 0; round < 8; ++round) {
        float excess = 0.0f, deficit = 0.0f;
        for (int k = 0; k < block; ++k)
            for (int j = 0; j < block; ++j)
                for (int i = 0; i < block; ++i) {
                    const float d = v[static_cast<std::size_t>((k * block + j) * block + i)];
                    const float r = kern::dmPlaneBlockDistance(plane.x, plane.y, plane.z, plane.w, glm::ivec3(i, j, k));
                    excess = std::max(excess, r - d);
                    // A voxel a surface may cross (0) reads 0 by the bound; any other must read
                    // more than 0, or the march would test it for the surface for nothing.
                    deficit = std::max(deficit, d > 0.0f && !(r > 0.0f) ? std::numeric_limits<float>::infinity() : d - r);
                }
        if (excess == 0.0f) return deficit <= maxDeficit;
        plane.x = std::nextafter(plane.x - excess, -std::numeric_limits<float>::infinity());
    }
    return false;
}
} // namespace detail

/// Compresses `m` in blocks of `block`^3 voxels (block divides the sizes). `maxSpread` >= 0
/// (voxels; +Inf: only blocks that hold a 0 and a non-zero value go to the atlas, and free
/// blocks keep their minimum, the paper's rule). ArgumentError otherwise.
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
    const std::size_t atlasMax = (std::size_t(1) << 30) - 1;
    const int n = block * block * block;
    std::vector<float> v(static_cast<std::size_t>(n));
    std::vector<std::size_t> planeWords; // grid words that hold a plane's index until the atlas is complete
    for (int cone = 0; cone < m.cones.count(); ++cone)
        for (int bz = 0; bz < c.gz; ++bz)
            for (int by = 0; by < c.gy; ++by)
                for (int bx = 0; bx < c.gx; ++bx) {
                    for (int k = 0; k < block; ++k)
                        for (int j = 0; j < block; ++j)
                            for (int i = 0; i < block; ++i)
                                v[static_cast<std::size_t>((k * block + j) * block + i)] = m.at(cone, bx * block + i, by * block + j, bz * block + k);
                    const float lo = *std::min_element(v.begin(), v.end()), hi = std::max(*std::max_element(v.begin(), v.end()), 0.0f);
                    std::uint32_t word;
                    glm::vec4 plane;
                    if (hi == 0.0f || (lo > 0.0f && hi - lo <= maxSpread)) { // all 0 (inside the solid), or even free space: one value
                        std::memcpy(&word, &lo, sizeof word);
                    } else if (std::isfinite(maxSpread) && detail::fitPlaneBlock(v, block, 0.5f * maxSpread, plane)) {
                        word = 0xC0000000u | static_cast<std::uint32_t>(c.planeBlocks()); // the index for now: the offset below
                        planeWords.push_back(c.gridIndex(cone, bx, by, bz));
                        for (int q = 0; q < 4; ++q) c.planes.push_back(plane[q]);
                    } else {
                        const std::size_t index = c.atlasBlocks();
                        if (index > atlasMax) throw ArgumentError("compressDdm: more than 2^30 atlas blocks");
                        c.atlas.insert(c.atlas.end(), v.begin(), v.end());
                        word = 0x80000000u | static_cast<std::uint32_t>(index);
                    }
                    c.grid[c.gridIndex(cone, bx, by, bz)] = word;
                }
    // A plane word holds the offset of its record in the atlas buffer (atlas, then planes).
    if (c.atlas.size() + c.planes.size() > atlasMax) throw ArgumentError("compressDdm: more than 2^30 atlas values");
    for (std::size_t at : planeWords) c.grid[at] = 0xC0000000u | static_cast<std::uint32_t>(c.atlas.size() + 4 * (c.grid[at] & 0x3fffffffu));
    return c;
}

} // namespace dispmap
