#pragma once
// TileSet: the displacement function D(face, u, v) of a whole mesh as biquadratic B-spline
// tiles (one per Ptex face) with one-texel overlap and a mip pyramid per tile, plus the
// packed GPU layout (one 2D texture, 16-byte patch records). Nießner & Loop 2013, §4.
//
// This header needs only GLM and the standard library. Building a TileSet from a mesh is in
// tile_builder.h (OpenSubdiv); files are in tile_file.h.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "dispmap/core/error.h"
#include "dispmap/kernels/bspline.h"
#include "dispmap/kernels/lod.h"
#include "dispmap/kernels/tile.h"

namespace dispmap {

/// Smallest and largest log2 tile size. k = 8 (256 x 256) keeps a footprint inside the
/// 16-bit texture offsets of the patch record with room for packing; k >= 1 per the paper.
inline constexpr int kMinTileLog2 = 1;
inline constexpr int kMaxTileLog2 = 8;

/// How coarser mip levels are computed from finer ones (§4.3; docs/design.md).
enum class MipFilter : std::uint8_t {
    Haar = 0,     ///< mean of the 2 x 2 children: smooth, positive weights, shifts curved data
    BWavelet = 1, ///< lifted quadratic B-wavelet low-pass (-1, 3, 3, -1)/4: exact on quadratics
};
inline const char* toString(MipFilter f) { return f == MipFilter::Haar ? "haar" : "bwavelet"; }

/// Size of a tile level with s x s sub-patches, overlap included.
inline constexpr std::size_t levelTexels(int s) {
    return static_cast<std::size_t>(s + 2) * static_cast<std::size_t>(s + 2);
}

/// One tile: s = 2^k sub-patches per side, levels m = 0..k-1 (size s >> m, finest first),
/// each (s_m + 2)^2 coefficients stored row by row: coefficient (a, b), a along u, b along
/// v, at index b * (s_m + 2) + a. See kernels/tile.h for the index conventions.
struct Tile {
    int k = 0;
    /// Per corner (0 at (0,0), 1 at (1,0), 2 at (1,1), 3 at (0,1)): k minus the smallest k
    /// of the tiles around that corner's vertex (§4.4).
    std::array<std::uint8_t, 4> sizeDifferences{};
    std::vector<float> coefficients; ///< all levels, finest first

    int size() const { return 1 << k; }
    int levelCount() const { return k; }
    static std::size_t levelOffset(int k, int m) {
        std::size_t off = 0;
        for (int j = 0; j < m; ++j) off += levelTexels((1 << k) >> j);
        return off;
    }
    static std::size_t totalTexels(int k) { return levelOffset(k, k); }
    int levelSize(int m) const { return size() >> m; }
    float* level(int m) { return coefficients.data() + levelOffset(k, m); }
    const float* level(int m) const { return coefficients.data() + levelOffset(k, m); }
    float& at(int m, int a, int b) { return level(m)[static_cast<std::size_t>(b * (levelSize(m) + 2) + a)]; }
    float at(int m, int a, int b) const {
        return level(m)[static_cast<std::size_t>(b * (levelSize(m) + 2) + a)];
    }
};

/// The 16-byte patch record of §5.4, laid out exactly as the paper's struct. A renderer
/// uploads an array of these; the shader reads each as a uvec4 (kernels/tile.h).
struct PatchRecord {
    std::uint16_t globalTextureOffsetXY[2];
    std::uint16_t localDomainOffsetXY[2];
    std::uint16_t tileSize;
    std::uint16_t rotation;
    std::uint8_t tileSizeDifferences[4];
};
static_assert(sizeof(PatchRecord) == 16, "the patch record must be 16 bytes (paper §5.4)");
static_assert(alignof(PatchRecord) <= 4, "the patch record must pack into uvec4 arrays");

/// The record as the four 32-bit words a shader reads (little-endian host assumed, as on
/// every platform Vulkan runs on).
inline glm::uvec4 recordWords(const PatchRecord& r) {
    glm::uvec4 w;
    static_assert(sizeof(w) == sizeof(r));
    std::memcpy(&w, &r, sizeof(r));
    return w;
}

/// How the packed tiles' texels are stored for the GPU: 32-bit floats, or IEEE 16-bit half
/// floats (the paper's storage, §4.3: half the memory, about 3 decimal digits).
enum class TexelFormat { Float, Half };

inline const char* toString(TexelFormat f) { return f == TexelFormat::Float ? "float" : "half"; }

/// The IEEE 754 binary16 bits nearest to x, ties to even (what an R16F upload or
/// unpackHalf2x16 decodes exactly back with halfValue). |x| >= 65520 gives infinity, NaN a NaN.
/// Encoding happens here, on the CPU, so that the GPU only decodes, which is exact: the CPU
/// and GPU lookups of half texels stay bit for bit the same.
inline std::uint16_t halfBits(float x) {
    std::uint32_t f = 0;
    std::memcpy(&f, &x, sizeof f);
    const auto sign = static_cast<std::uint32_t>((f >> 16) & 0x8000u);
    const std::uint32_t a = f & 0x7fffffffu;
    if (a > 0x7f800000u) return static_cast<std::uint16_t>(sign | 0x7e00u);  // NaN
    if (a >= 0x477ff000u) return static_cast<std::uint16_t>(sign | 0x7c00u); // 65520 and up: infinity
    if (a < 0x38800000u) {
        // below 2^-14: a subnormal half, a multiple of 2^-24 (the scaling is exact; ties to even)
        const float m = std::nearbyint(std::fabs(x) * 16777216.0f);
        return static_cast<std::uint16_t>(sign | static_cast<std::uint32_t>(m));
    }
    std::uint32_t h = (a - 0x38000000u) >> 13; // the exponent rebiased from 127 to 15
    const std::uint32_t rest = a & 0x1fffu;    // the 13 bits dropped
    if (rest > 0x1000u || (rest == 0x1000u && (h & 1u))) ++h; // a carry moves into the exponent, as it should
    return static_cast<std::uint16_t>(sign | h);
}

/// The value of half-float bits h (exact in float).
inline float halfValue(std::uint16_t h) {
    const std::uint32_t sign = (static_cast<std::uint32_t>(h) & 0x8000u) << 16;
    const std::uint32_t e = (static_cast<std::uint32_t>(h) >> 10) & 0x1fu, m = static_cast<std::uint32_t>(h) & 0x3ffu;
    if (e == 0) {
        const float v = std::ldexp(static_cast<float>(m), -24);
        return sign ? -v : v;
    }
    const std::uint32_t f = sign | (e == 31 ? 0x7f800000u : (e + 112u) << 23) | (m << 13);
    float out = 0;
    std::memcpy(&out, &f, sizeof out);
    return out;
}

/// All tiles packed into one texture: each tile's footprint (kernels dmTileFootprint) at a
/// per-tile offset; unused texels hold 0.
struct PackedTiles {
    int width = 0, height = 0;
    /// Row by row, width * height; with TexelFormat::Half each is a half float's value (the
    /// upload is halfTexels()), so that sampleD1 reads what the GPU reads.
    std::vector<float> texels;
    TexelFormat format = TexelFormat::Float;
    std::vector<PatchRecord> records;   ///< one per tile (depth 0: the tile is the patch)
    std::size_t usedTexels = 0;         ///< texels inside footprints
    std::size_t paperTexels = 0;        ///< sum over tiles of (1.5 s + 4)(s + 2), §4.3

    /// The texel rectangle (x, y, width, height) of record `index`'s footprint.
    glm::ivec4 footprint(int index) const {
        const PatchRecord& r = records.at(static_cast<std::size_t>(index));
        const glm::ivec2 fp = kern::dmTileFootprint(kern::dmTileLog2(r.tileSize));
        return {r.globalTextureOffsetXY[0], r.globalTextureOffsetXY[1], fp.x, fp.y};
    }
    /// Writes every level of `tile` into the footprint of record `index` (an edited tile of the
    /// size it was packed with: pack() lays out by size, so the layout stays), rounded to half
    /// floats with TexelFormat::Half. ArgumentError for an index out of range, another size, or
    /// (half) a coefficient beyond the half range.
    void writeTile(int index, const Tile& tile) {
        checkTile(index, tile);
        const PatchRecord& r = records[static_cast<std::size_t>(index)];
        const glm::ivec2 at(r.globalTextureOffsetXY[0], r.globalTextureOffsetXY[1]);
        for (int m = 0; m < tile.k; ++m) {
            const glm::ivec2 o = at + kern::dmMipOffset(tile.k, m);
            const int n = tile.levelSize(m) + 2;
            for (int b = 0; b < n; ++b)
                for (int a = 0; a < n; ++a)
                    texels[static_cast<std::size_t>(o.y + b) * static_cast<std::size_t>(width) + static_cast<std::size_t>(o.x + a)] =
                        rounded(tile.at(m, a, b), index);
        }
    }

    /// What writeTile checks before it writes: the index, the size, and (half texels) the range.
    void checkTile(int index, const Tile& tile) const {
        if (index < 0 || static_cast<std::size_t>(index) >= records.size())
            throw ArgumentError("packed tiles: record " + std::to_string(index) + " out of range");
        const PatchRecord& r = records[static_cast<std::size_t>(index)];
        if (tile.size() != r.tileSize)
            throw ArgumentError("packed tiles: tile " + std::to_string(index) + " has size " + std::to_string(tile.size()) +
                                ", packed with " + std::to_string(r.tileSize) + " (re-pack after changing sizes)");
        if (format == TexelFormat::Half)
            for (float c : tile.coefficients) (void)rounded(c, index);
    }

    /// Stores every texel as a half float from now on (TexelFormat::Half): the texels are
    /// rounded to the nearest half, and so are the tiles writeTile writes later. ArgumentError
    /// naming the tile for a coefficient beyond the half range (|c| >= 65520), before any
    /// texel changes.
    void useHalf() {
        std::vector<float> out(texels.size());
        for (std::size_t i = 0; i < texels.size(); ++i) {
            out[i] = halfValue(halfBits(texels[i]));
            if (std::isinf(out[i])) {
                const int x = static_cast<int>(i % static_cast<std::size_t>(width)), y = static_cast<int>(i / static_cast<std::size_t>(width));
                int tile = -1;
                for (std::size_t r = 0; r < records.size() && tile < 0; ++r) {
                    const glm::ivec4 fp = footprint(static_cast<int>(r));
                    if (x >= fp.x && x < fp.x + fp.z && y >= fp.y && y < fp.y + fp.w) tile = static_cast<int>(r);
                }
                throw ArgumentError("packed tiles: tile " + std::to_string(tile) + " holds " + std::to_string(texels[i]) +
                                    ", beyond the half-float range (65504): keep float texels");
            }
        }
        texels = std::move(out);
        format = TexelFormat::Half;
    }

    /// The half-float bits of `count` texels from `first` (row by row): what a half-float
    /// storage buffer or R16F texture holds. Meaningful after useHalf().
    std::vector<std::uint16_t> halfTexels(std::size_t first = 0, std::size_t count = static_cast<std::size_t>(-1)) const {
        first = std::min(first, texels.size());
        count = std::min(count, texels.size() - first);
        std::vector<std::uint16_t> out(count);
        for (std::size_t i = 0; i < count; ++i) out[i] = halfBits(texels[first + i]);
        return out;
    }

  private:
    float rounded(float c, int index) const {
        if (format == TexelFormat::Float) return c;
        const float h = halfValue(halfBits(c));
        if (std::isinf(h))
            throw ArgumentError("packed tiles: tile " + std::to_string(index) + " holds " + std::to_string(c) +
                                ", beyond the half-float range (65504): keep float texels");
        return h;
    }

  public:
    /// The renderer's displacement lookup on the CPU, kernel for kernel what the tessellation
    /// evaluation shader does: (D, D_u, D_v) with respect to the tile's (u, v) of `record`,
    /// reading the two mip levels that resolution rho selects (dmSelectMips, clamped by the
    /// §4.4 maximum at (u, v)) from the packed texture and blending them (dmBlendMips).
    template <typename real> glm::vec<3, real> sampleD1(int record, glm::vec<2, real> uv, real rho) const {
        const glm::uvec4 r = recordWords(records.at(static_cast<std::size_t>(record)));
        const int s = kern::dmRecordTileSize(r);
        const int k = kern::dmTileLog2(s);
        const real maxRes = kern::dmMaxResolution(k, kern::dmUnpackSizeDifferences(r.w), uv);
        int mFine = 0, mCoarse = 0;
        const real w = kern::dmSelectMips(rho, maxRes, k, mFine, mCoarse);
        auto level = [&](int m) {
            glm::ivec2 texel;
            const glm::vec<2, real> t = kern::dmPackedLocate(r, m, uv, texel);
            glm::mat<3, 3, real> c;
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    c[i][j] = static_cast<real>(texels[static_cast<std::size_t>(texel.y + j) * static_cast<std::size_t>(width) +
                                                       static_cast<std::size_t>(texel.x + i)]);
            return kern::dmTileD1(c, t, s >> m);
        };
        return kern::dmBlendMips(level(mCoarse), level(mFine), w);
    }
};

class TileSet {
  public:
    MipFilter filter = MipFilter::Haar;
    std::vector<Tile> tiles;            ///< indexed by Ptex face id
    std::uint64_t topologyHash = 0;     ///< fingerprint of the mesh topology it was built for

    int tileCount() const { return static_cast<int>(tiles.size()); }

    /// The 3 x 3 coefficients of the sub-patch containing (u, v) at level m, the local
    /// parameter t and the level's size s (the factor of face derivatives). m is clamped to
    /// the tile's levels.
    template <typename real>
    glm::mat<3, 3, real> subpatch(int tile, int m, glm::vec<2, real> uv, glm::vec<2, real>& t, real& s) const {
        const Tile& tl = tiles.at(static_cast<std::size_t>(tile));
        m = std::min(std::max(m, 0), tl.k - 1);
        glm::ivec2 cell;
        t = kern::dmSubpatch(uv, tl.levelSize(m), cell);
        s = static_cast<real>(tl.levelSize(m));
        glm::mat<3, 3, real> c;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) c[i][j] = static_cast<real>(tl.at(m, cell.x + i, cell.y + j));
        return c;
    }

    /// D at (u, v) of a tile's level m.
    template <typename real> real evaluate(int tile, int m, glm::vec<2, real> uv) const {
        glm::vec<2, real> t;
        real s;
        auto c = subpatch(tile, m, uv, t, s);
        return kern::dmBiquadratic(c, t);
    }
    /// (D, D_u, D_v) with respect to the face's (u, v) (factor s of the level applied).
    template <typename real> glm::vec<3, real> evaluateD1(int tile, int m, glm::vec<2, real> uv) const {
        glm::vec<2, real> t;
        real s;
        auto c = subpatch(tile, m, uv, t, s);
        return kern::dmTileD1(c, t, static_cast<int>(s));
    }
    /// (D_uu, D_uv, D_vv) with respect to the face's (u, v).
    template <typename real> glm::vec<3, real> evaluateD2(int tile, int m, glm::vec<2, real> uv) const {
        glm::vec<2, real> t;
        real s;
        auto c = subpatch(tile, m, uv, t, s);
        return kern::dmBiquadraticD2(c, t) * (s * s);
    }

    /// Packs every tile into one texture (shelf packing, tallest first) and writes the patch
    /// records. Throws ArgumentError if the texture would exceed the 16-bit offsets.
    PackedTiles pack() const;

    /// evaluateD1 along rows v = const of one level of one tile, for many u: see below.
    template <typename real> class Row;
};

/// (D, D_u, D_v) of one level of one tile along a row v = const, for many u, or along a
/// column u = const, for many v (alongV). The three coefficient rows (columns) the line reads
/// are collapsed once per texel across it with the basis of the fixed coordinate and its
/// derivative (the texels the line's points read, each once), so each point sums 3 + 3
/// collapsed values with the basis along the line where evaluateD1 gathers 9 coefficients and
/// multiplies twice. The result is evaluateD1(tile, m, (u, v)) to rounding, not bit for bit
/// (the same 9 products summed in another order). The row keeps a pointer to the set; one per
/// thread. setRow() starts a line, at() reads it.
template <typename real> class TileSet::Row {
  public:
    using vec3 = glm::vec<3, real>;
    /// Level m of `tile` (clamped to the tile's levels, as subpatch()), along u (rows) or along
    /// v (columns). Throws std::out_of_range for a tile index out of range, as tiles.at().
    Row(const TileSet& set, int tile, int m, bool alongV = false)
        : tile_(&set.tiles.at(static_cast<std::size_t>(tile))), alongV_(alongV) {
        m_ = std::min(std::max(m, 0), tile_->k - 1);
        size_ = tile_->levelSize(m_);
        collapsed_.resize(static_cast<std::size_t>(size_ + 2));
        stamp_.assign(static_cast<std::size_t>(size_ + 2), 0);
    }
    /// Starts the line at `fixed` (v of a row, u of a column) and collapses the texels that its
    /// points xs read (coordinates clamped into [0, 1], as dmSubpatch). Throws ArgumentError for
    /// a value that is not finite.
    void setRow(real fixed, std::span<const real> xs) {
        if (!std::isfinite(fixed)) throw ArgumentError("tile row: its fixed coordinate is not finite");
        glm::ivec2 cell;
        const glm::vec<2, real> t = kern::dmSubpatch(glm::vec<2, real>(fixed, fixed), size_, cell);
        ++line_;
        const real tf = alongV_ ? t.x : t.y;
        const glm::vec<3, real> b = kern::dmBSpline2(tf), db = kern::dmBSpline2D1(tf);
        const std::size_t stride = static_cast<std::size_t>(size_ + 2);
        // Coefficient (a, c) with a along the line and c = 0..2 across it, from the first of the
        // three texel rows (columns) the line reads.
        const std::size_t first = static_cast<std::size_t>(alongV_ ? cell.x : cell.y);
        const float* level = tile_->level(m_);
        const std::size_t stepAlong = alongV_ ? stride : 1, stepAcross = alongV_ ? 1 : stride;
        const float* base = level + first * stepAcross;
        for (const real x : xs) {
            if (!std::isfinite(x)) throw ArgumentError("tile row: a point's coordinate is not finite");
            kern::dmSubpatch(glm::vec<2, real>(x, x), size_, cell);
            const int c0 = alongV_ ? cell.y : cell.x;
            for (int q = 0; q < 3; ++q) {
                const std::size_t a = static_cast<std::size_t>(c0 + q);
                if (stamp_[a] == line_) continue;
                stamp_[a] = line_;
                const float* p = base + a * stepAlong;
                const glm::vec<3, real> across(static_cast<real>(p[0]), static_cast<real>(p[stepAcross]),
                                               static_cast<real>(p[2 * stepAcross]));
                collapsed_[a] = glm::vec<2, real>(kern::dmDot3(across, b), kern::dmDot3(across, db));
            }
        }
    }
    /// (D, D_u, D_v) with respect to the face's (u, v) at the line's point x (u along a row, v
    /// along a column). Throws ArgumentError for x not finite or reading texels setRow() did not
    /// collapse (x not among its points, or no setRow()).
    vec3 at(real x) {
        if (!std::isfinite(x)) throw ArgumentError("tile row: a point's coordinate is not finite");
        glm::ivec2 cell;
        const glm::vec<2, real> t = kern::dmSubpatch(glm::vec<2, real>(x, x), size_, cell);
        const int c0 = alongV_ ? cell.y : cell.x;
        vec3 c(0), cd(0); // the three texels collapsed across the line: values and derivatives across
        for (int q = 0; q < 3; ++q) {
            const std::size_t a = static_cast<std::size_t>(c0 + q);
            if (stamp_[a] != line_ || line_ == 0)
                throw ArgumentError("tile row: the point " + std::to_string(double(x)) + " reads texels its row did not collapse");
            c[q] = collapsed_[a].x;
            cd[q] = collapsed_[a].y;
        }
        const real s = real(size_), tx = alongV_ ? t.y : t.x;
        const glm::vec<3, real> b = kern::dmBSpline2(tx);
        const real along = kern::dmDot3(c, kern::dmBSpline2D1(tx)) * s, across = kern::dmDot3(cd, b) * s;
        return vec3(kern::dmDot3(c, b), alongV_ ? across : along, alongV_ ? along : across);
    }

  private:
    const Tile* tile_;
    bool alongV_;
    int m_ = 0, size_ = 1;
    std::uint32_t line_ = 0; ///< lines started; a texel is collapsed for this line when its stamp equals it
    std::vector<glm::vec<2, real>> collapsed_;
    std::vector<std::uint32_t> stamp_;
};

inline PackedTiles TileSet::pack() const {
    PackedTiles out;
    if (tiles.empty()) return out;
    std::vector<int> order(tiles.size());
    std::size_t area = 0;
    int widest = 0;
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        order[i] = static_cast<int>(i);
        glm::ivec2 fp = kern::dmTileFootprint(tiles[i].k);
        area += static_cast<std::size_t>(fp.x) * static_cast<std::size_t>(fp.y);
        widest = std::max(widest, fp.x);
        const double s = tiles[i].size();
        out.paperTexels += static_cast<std::size_t>((1.5 * s + 4.0) * (s + 2.0));
    }
    out.usedTexels = area;
    // Stable order: larger tiles first, then by face id, so the layout is deterministic.
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return tiles[static_cast<std::size_t>(a)].k > tiles[static_cast<std::size_t>(b)].k; });
    const int width = std::max(widest, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(area) * 1.1))));
    std::vector<glm::ivec2> at(tiles.size());
    int x = 0, y = 0, shelf = 0;
    for (int id : order) {
        glm::ivec2 fp = kern::dmTileFootprint(tiles[static_cast<std::size_t>(id)].k);
        if (x + fp.x > width) {
            x = 0;
            y += shelf;
            shelf = 0;
        }
        at[static_cast<std::size_t>(id)] = glm::ivec2(x, y);
        x += fp.x;
        shelf = std::max(shelf, fp.y);
    }
    out.width = width;
    out.height = y + shelf;
    if (out.width > 65535 || out.height > 65535)
        throw ArgumentError("tile set too large to pack: " + std::to_string(out.width) + " x " +
                            std::to_string(out.height) + " texels exceeds the 16-bit patch record offsets");
    out.texels.assign(static_cast<std::size_t>(out.width) * static_cast<std::size_t>(out.height), 0.0f);
    out.records.resize(tiles.size());
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        const Tile& t = tiles[i];
        PatchRecord& r = out.records[i];
        r.globalTextureOffsetXY[0] = static_cast<std::uint16_t>(at[i].x);
        r.globalTextureOffsetXY[1] = static_cast<std::uint16_t>(at[i].y);
        r.localDomainOffsetXY[0] = r.localDomainOffsetXY[1] = 0;
        r.tileSize = static_cast<std::uint16_t>(t.size());
        r.rotation = 0;
        for (int c = 0; c < 4; ++c) r.tileSizeDifferences[c] = t.sizeDifferences[static_cast<std::size_t>(c)];
        out.writeTile(static_cast<int>(i), t);
    }
    return out;
}

} // namespace dispmap
