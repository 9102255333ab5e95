// Half-float texels (TexelFormat::Half): the CPU encoder against IEEE binary16, and packed
// tiles stored as halves.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "dispmap/core/tileset.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/tile_builder.h"

namespace dmtest_test_half {

using namespace dispmap;
using Catch::Contains;

TEST_CASE("half floats: every finite half round-trips, ties go to even, others to the nearest", "[half]") {
    // Every one of the 63,488 finite halves (and both zeros) decodes and encodes back to itself.
    int finite = 0;
    for (std::uint32_t h = 0; h < 0x10000u; ++h) {
        const auto bits = static_cast<std::uint16_t>(h);
        if (((h >> 10) & 0x1fu) == 0x1fu) continue; // infinities and NaNs
        ++finite;
        REQUIRE(halfBits(halfValue(bits)) == bits);
    }
    CHECK(finite == 63488);
    // Known values.
    CHECK(halfValue(0x3c00u) == 1.0f);
    CHECK(halfValue(0x7bffu) == 65504.0f);
    CHECK(halfValue(0x0001u) == std::ldexp(1.0f, -24)); // smallest subnormal
    CHECK(halfValue(0x0400u) == std::ldexp(1.0f, -14)); // smallest normal
    CHECK(halfBits(-2.0f) == 0xc000u);
    CHECK(std::isinf(halfValue(halfBits(65520.0f))));   // the midpoint above 65504 rounds to infinity (65504 is odd)
    CHECK(halfBits(65519.996f) == 0x7bffu);
    CHECK(std::isnan(halfValue(halfBits(std::numeric_limits<float>::quiet_NaN()))));
    // Midpoints between neighbours go to the even one; anything else to the nearest.
    for (std::uint32_t h = 0x0000u; h < 0x7bffu; ++h) {
        const float a = halfValue(static_cast<std::uint16_t>(h)), b = halfValue(static_cast<std::uint16_t>(h + 1));
        const float mid = a + (b - a) / 2; // exact in float: halves have 11 significant bits
        REQUIRE(halfBits(mid) == ((h & 1u) ? h + 1 : h));
        REQUIRE(halfBits(-mid) == (((h & 1u) ? h + 1 : h) | 0x8000u));
        REQUIRE(halfBits(std::nextafter(mid, a)) == h);
        REQUIRE(halfBits(std::nextafter(mid, b)) == h + 1);
    }
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> d(-70000.0f, 70000.0f);
    for (int i = 0; i < 100000; ++i) {
        const float x = i % 2 ? d(rng) : d(rng) * 1e-6f;
        const std::uint16_t h = halfBits(x);
        const float v = halfValue(h);
        if (std::isinf(v)) {
            REQUIRE(std::abs(x) >= 65520.0f);
            continue;
        }
        // no other half is nearer
        const float up = halfValue(static_cast<std::uint16_t>(h + 1)), down = halfValue(static_cast<std::uint16_t>(h - 1));
        if ((h & 0x7fffu) != 0) REQUIRE(std::abs(x - v) <= std::abs(x - down));
        if ((h & 0x7fffu) != 0x7bffu) REQUIRE(std::abs(x - v) <= std::abs(x - up));
    }
}

TEST_CASE("packed tiles as halves: texels rounded, edits rounded, the range checked", "[half]") {
    const ControlMesh mesh = builtin::defaultMesh();
    const TileSet ts = buildTiles(mesh, uniformTileSizes(mesh, 4), FunctionSource(builtin::defaultDisplacement));
    PackedTiles p = ts.pack();
    const PackedTiles full = p;
    p.useHalf();
    CHECK(p.format == TexelFormat::Half);
    double worst = 0.0, maxAbs = 0.0;
    for (std::size_t i = 0; i < p.texels.size(); ++i) {
        REQUIRE(halfValue(halfBits(p.texels[i])) == p.texels[i]); // every texel is a half
        worst = std::max(worst, static_cast<double>(std::abs(p.texels[i] - full.texels[i])));
        maxAbs = std::max(maxAbs, static_cast<double>(std::abs(full.texels[i])));
    }
    CHECK(worst <= maxAbs * std::ldexp(1.0, -11)); // half an ulp of 11 significant bits
    CHECK(worst > 0.0);
    const std::vector<std::uint16_t> bits = p.halfTexels(3, 5);
    REQUIRE(bits.size() == 5);
    CHECK(halfValue(bits[2]) == p.texels[5]);
    // The lookup on half texels: D within the halves' rounding of the float lookup.
    for (int r = 0; r < static_cast<int>(p.records.size()); ++r) {
        const glm::vec3 a = p.sampleD1<float>(r, glm::vec2(0.3f, 0.7f), 3.5f), b = full.sampleD1<float>(r, glm::vec2(0.3f, 0.7f), 3.5f);
        REQUIRE(std::abs(a.x - b.x) <= static_cast<float>(maxAbs) * 1e-3f);
    }
    // A tile beyond the half range: refused, nothing written.
    Tile big = ts.tiles[2];
    big.coefficients[7] = 1e5f;
    const std::vector<float> before = p.texels;
    REQUIRE_THROWS_WITH(p.writeTile(2, big), Contains("tile 2 holds") && Contains("beyond the half-float range"));
    CHECK(p.texels == before);
    PackedTiles q = full;
    q.texels[11] = -7e4f;
    REQUIRE_THROWS_WITH(q.useHalf(), Contains("beyond the half-float range"));
    CHECK(q.format == TexelFormat::Float);
    // An edit is rounded as it is written.
    Tile edited = ts.tiles[2];
    for (float& c : edited.coefficients) c *= 1.0001f;
    p.writeTile(2, edited);
    const glm::ivec4 fp = p.footprint(2);
    const float t = p.texels[static_cast<std::size_t>(fp.y + 1) * static_cast<std::size_t>(p.width) + static_cast<std::size_t>(fp.x + 1)];
    CHECK(halfValue(halfBits(t)) == t);
    CHECK(t == halfValue(halfBits(edited.at(0, 1, 1))));
}

} // namespace dmtest_test_half
