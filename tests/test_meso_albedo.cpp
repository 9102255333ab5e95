// The mesostructure's albedo (meso/albedo.h, kern::dmMesoImage): the word layout, the box
// mips, bilinear and trilinear sampling against closed forms, float against double, the
// footprint's level, bad inputs, and the scene's "albedo" and "mips" keys.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "dispmap/io/png.h"
#include "dispmap/meso/march.h"
#include "dispmap/scene/meso.h"
#include "test_files.h"
#include "test_support.h"

namespace meso_albedo_test {
namespace {
using namespace dispmap;
using Catch::Contains;

// A w x h image whose red is 255 on odd x, green 10 y + x, blue 7, alpha 255.
std::vector<std::uint8_t> pattern(int w, int h) {
    std::vector<std::uint8_t> px(4 * static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const std::size_t i = 4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x));
            px[i] = x % 2 ? 255 : 0;
            px[i + 1] = static_cast<std::uint8_t>((10 * y + x) % 256);
            px[i + 2] = 7;
            px[i + 3] = 255;
        }
    return px;
}

TEST_CASE("albedo mips are box averages down to one texel", "[meso][albedo]") {
    const MesoAlbedo a = mesoAlbedo(8, 4, pattern(8, 4));
    REQUIRE(a.levels() == 4); // 8 x 4, 4 x 2, 2 x 1, 1 x 1
    CHECK((a.width(1) == 4 && a.height(1) == 2 && a.width(2) == 2 && a.height(2) == 1 && a.width(3) == 1 && a.height(3) == 1));
    CHECK(a.words.size() == 1 + 4 * 4 + 2 + 32 + 8 + 2 + 1); // count, levels, shift, texels
    CHECK(a.shift() == glm::vec2(0.0f));
    // Level 1 texel (1, 0): level-0 texels x 2..3, y 0..1: red (0 + 255 + 0 + 255) / 4 rounded,
    // green (2 + 3 + 12 + 13) / 4 = 7.5, rounded half up to 8.
    const std::uint32_t t = a.texel(1, 1, 0);
    CHECK((t & 255u) == 128u);
    CHECK(((t >> 8) & 255u) == 8u);
    CHECK(((t >> 16) & 255u) == 7u);
    CHECK(a.levels() == 4);
    // Without mips: level 0 only.
    CHECK(mesoAlbedo(8, 4, pattern(8, 4), false).levels() == 1);
    // Odd sizes: the last row / column dropped, at least one texel.
    const MesoAlbedo odd = mesoAlbedo(5, 1, pattern(5, 1));
    CHECK((odd.levels() == 3 && odd.width(1) == 2 && odd.height(1) == 1 && odd.width(2) == 1));
}

TEST_CASE("albedo sampling: bilinear between texels, wrapping, trilinear between levels", "[meso][albedo]") {
    const MesoAlbedo a = mesoAlbedo(4, 4, pattern(4, 4));
    const auto at = [&](double s, double t, double lod) { return glm::dvec4(sampleMesoAlbedo<double>(a, {s, t}, lod)) * 255.0; };
    // Texel (x, y) sits at (x / 4, y / 4): exactly its own colour there.
    CHECK(at(0.25, 0.5, 0).x == 255.0);
    CHECK(at(0.25, 0.5, 0).y == 21.0);
    // Half way between texels 1 and 2 of row 0: the mean.
    CHECK(at(0.375, 0.0, 0).x == Approx(127.5));
    CHECK(at(0.375, 0.0, 0).y == Approx(1.5));
    // Wrapping: a whole number of tiles away, negative too, the same colour; between the last
    // texel and the first across the seam, their mean.
    CHECK(at(-6.75, 5.5, 0) == at(0.25, 0.5, 0));
    CHECK(at(0.875, 0.0, 0).y == Approx(1.5)); // texels 3 (green 3) and 0 (green 0)
    // The coarsest level is the mean of everything (rounded per level), whatever the point;
    // levels beyond the pyramid clamp to it; a fraction mixes two levels.
    CHECK(at(0.3, 0.7, 2.0) == at(0.9, 0.1, 7.5));
    const glm::dvec4 mix = at(0.25, 0.5, 0.25);
    CHECK(glm::length(mix - (0.75 * at(0.25, 0.5, 0) + 0.25 * at(0.25, 0.5, 1))) < 1e-9);
    // Float against double: the same operations, float rounding of values up to 1.
    std::mt19937 g(3);
    std::uniform_real_distribution<double> u(-3.0, 3.0);
    double worst = 0;
    for (int i = 0; i < 1000; ++i) {
        const glm::dvec2 p(u(g), u(g));
        const double lod = std::abs(u(g));
        worst = std::max(worst, glm::length(glm::dvec4(sampleMesoAlbedo<float>(a, p, lod)) - glm::dvec4(sampleMesoAlbedo<double>(a, p, lod))));
    }
    CHECK(worst < 1e-5); // a few float ULP of O(1) values through two lerps
    // A shift (texels of level 0) moves where every level is read: (s, t) shifted reads what
    // (s + shift.x / w, t + shift.y / h) reads unshifted, in both precisions and on every level.
    const MesoAlbedo moved = mesoAlbedo(4, 4, pattern(4, 4), true, glm::vec2(1.5f, -0.25f));
    CHECK(moved.shift() == glm::vec2(1.5f, -0.25f));
    for (int i = 0; i < 200; ++i) {
        const glm::dvec2 p(u(g), u(g));
        const double lod = std::abs(u(g)) / 2;
        const glm::dvec2 q = p + glm::dvec2(1.5 / 4, -0.25 / 4);
        CHECK(glm::length(glm::dvec4(sampleMesoAlbedo<double>(moved, p, lod)) - glm::dvec4(sampleMesoAlbedo<double>(a, q, lod))) < 1e-12);
        CHECK(glm::length(glm::dvec4(sampleMesoAlbedo<float>(moved, p, lod)) - glm::dvec4(sampleMesoAlbedo<float>(a, q, lod))) < 1e-5);
    }
}

TEST_CASE("the albedo's level follows the pixel's footprint", "[meso][albedo]") {
    const glm::dvec2 size(256, 128);
    CHECK(kern::dmMesoImageLod(glm::dvec2(1.0 / 256, 0), glm::dvec2(0, 1.0 / 128), size) == 0.0); // a texel a pixel
    CHECK(kern::dmMesoImageLod(glm::dvec2(4.0 / 256, 0), glm::dvec2(0, 1.0 / 128), size) == Approx(2.0)); // 4 texels in x
    CHECK(kern::dmMesoImageLod(glm::dvec2(0.1 / 256, 0), glm::dvec2(0, 0.1 / 128), size) == 0.0);  // magnified: level 0
}

TEST_CASE("bad albedos are clear errors", "[meso][albedo][inputs]") {
    CHECK_THROWS_WITH(mesoAlbedo(0, 4, {}), Contains("image size 0 x 4 out of range"));
    CHECK_THROWS_WITH(mesoAlbedo(4097, 1, std::vector<std::uint8_t>(4 * 4097)), Contains("out of range (1 .. 4096)"));
    CHECK_THROWS_WITH(mesoAlbedo(4, 4, std::vector<std::uint8_t>(63)), Contains("63 bytes for 4 x 4 RGBA texels"));
    CHECK_THROWS_WITH(mesoAlbedo(4, 4, std::vector<std::uint8_t>(64), true, glm::vec2(std::nanf(""), 0.0f)), Contains("not finite or beyond"));
    CHECK_THROWS_WITH(mesoAlbedo(4, 2, std::vector<std::uint8_t>(32), true, glm::vec2(0.0f, 2.5f)), Contains("not finite or beyond"));
    CHECK_THROWS_WITH(sampleMesoAlbedo<float>(MesoAlbedo{}, {0, 0}, 0), Contains("the albedo is empty"));
    const MesoAlbedo a = mesoAlbedo(2, 2, pattern(2, 2));
    CHECK_THROWS_WITH(sampleMesoAlbedo<float>(a, {std::nan(""), 0}, 0), Contains("not finite"));
    // Words that do not hold an image are refused before they are read: the layout before the
    // shift words (its texels where the shift now is), a shift that is not finite, a level
    // beyond the words.
    CHECK(mesoAlbedoProblem(a).empty());
    MesoAlbedo old;
    old.words = {1u, 5u, 2u, 2u, 0u, 0xff0000ffu, 0xff00ff00u, 0xffff0000u, 0xffffffffu};
    CHECK_THROWS_WITH(sampleMesoAlbedo<float>(old, {0, 0}, 0), Contains("texels do not lie within its words after the header"));
    MesoAlbedo nanShift = a;
    nanShift.words[static_cast<std::size_t>(1 + 4 * a.levels())] = 0x7fc00000u;
    CHECK_THROWS_WITH(sampleMesoAlbedo<double>(nanShift, {0, 0}, 0), Contains("shift is not finite"));
    MesoAlbedo cut = a;
    cut.words.resize(cut.words.size() - 1);
    CHECK_THROWS_WITH(sampleMesoAlbedo<double>(cut, {0, 0}, 0), Contains("do not lie within its words"));
    MesoAlbedo many = a;
    many.words[0] = 40;
    CHECK_THROWS_WITH(sampleMesoAlbedo<double>(many, {0, 0}, 0), Contains("level count 40 is not in 1 .. 32"));
}

TEST_CASE("a mesostructure scene's albedo", "[meso][albedo][scene]") {
    dmtest::TempDir dir("dispmap_albedo_");
    const std::vector<std::uint8_t> px = pattern(16, 8);
    writeRgbaPng((dir.path / "c.png").string(), 16, 8, px.data());
    const auto scene = [&](const std::string& json) { return parseMesoScene(nlohmann::json::parse(json), "a.json", dir.path.string()); };
    const MesoSceneDesc s = scene(R"({"mesostructure": {"albedo": "c.png"}})");
    const auto a = buildMesoSceneAlbedo(s);
    REQUIRE(a);
    CHECK((a->width() == 16 && a->height() == 8 && a->levels() == 5));
    CHECK(buildMesoSceneAlbedo(scene(R"({"mesostructure": {"albedo": "c.png"}, "effects": {"mips": false}})"))->levels() == 1);
    CHECK_FALSE(buildMesoSceneAlbedo(scene(R"({"mesostructure": {}})")));
    CHECK_THROWS_WITH(scene(R"({"mesostructure": {"albedo": 3}})"), Contains("'mesostructure.albedo' must be a file name"));
    CHECK_THROWS_WITH(scene(R"({"mesostructure": {"albedo": ""}})"), Contains("'mesostructure.albedo' is empty"));
    CHECK_THROWS_WITH(scene(R"({"mesostructure": {}, "effects": {"mips": 1}})"), Contains("'effects.mips' must be true or false"));
    CHECK_THROWS_AS(buildMesoSceneAlbedo(scene(R"({"mesostructure": {"albedo": "missing.png"}})")), FileError);
}

TEST_CASE("an albedo paired with the height image colours each field sample with the block it averages", "[meso][albedo][scene]") {
    // A smooth periodic image, as heights and as colour, 64 x 64; the field filtered to 16 x 16
    // (fx = 4). Sample (i, j) is the mean of texels 4i .. 4i + 3: its colour must be the image's
    // there, not the colour of texel 4i (1.5 texels off, what the albedo showed before
    // mesoImageShift).
    dmtest::TempDir dir("dispmap_albedo_shift_");
    const int n = 64;
    HeightImage h;
    h.width = h.height = n;
    RgbaImage c;
    c.width = c.height = n;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const double v = std::round(128 + 100 * std::sin(6.283185307179586 * x / n) * std::cos(6.283185307179586 * 2 * y / n));
            h.values.push_back(static_cast<float>(v / 255.0));
            for (int k = 0; k < 4; ++k) c.rgba.push_back(static_cast<std::uint8_t>(k == 3 ? 255 : v));
        }
    writeHeightPng16((dir.path / "h.png").string(), h);
    writeRgbaPng((dir.path / "c.png").string(), n, n, c.rgba.data());
    const MesoSceneDesc s = parseMesoScene(nlohmann::json::parse(R"({"mesostructure": {"height": "h.png", "size": 16, "layers": 16,
        "depth": 16, "albedo": "c.png"}, "effects": {"mips": false}})"), "s.json", dir.path.string());
    const MesoMaps maps = buildMesoSceneMaps(s);
    const auto albedo = buildMesoSceneAlbedo(s);
    REQUIRE(albedo);
    CHECK(detail::mesoImageShift(s, n, n) == glm::dvec2(1.5));
    double shifted = 0, before = 0;
    for (int j = 0; j < 16; ++j)
        for (int i = 0; i < 16; ++i) {
            const double field = double(maps.field.h[static_cast<std::size_t>(j * 16 + i)]) / 16.0 * 255.0; // the block's mean, in levels
            shifted = std::max(shifted, std::abs(255.0 * sampleMesoAlbedo<double>(*albedo, {i / 16.0, j / 16.0}, 0.0).x - field));
            before = std::max(before, std::abs(double(c.rgba[4 * static_cast<std::size_t>(4 * j * n + 4 * i)]) - field));
        }
    INFO("largest difference from the block's mean: " << shifted << " levels read at the sample, " << before << " at texel 4i");
    // The image is smooth: the block's mean and the bilinear value at its centre differ by the
    // curvature over 1.5 texels (about 100 (2 pi 2 / 64)^2 1.5^2 / 2 = 4.3 levels at most) plus
    // rounding; texel 4i is 1.5 texels off, about 100 (2 pi 2 / 64) 1.5 = 29 levels where the slope is steepest.
    CHECK(shifted < 6.0);
    CHECK(before > 3 * shifted);
    // The shift is applied where the image is read (MesoAlbedo::shift), not by resampling the
    // image: anywhere, the albedo is the original image's bilinear value 1.5 texels on, to
    // float rounding. A resampled copy (rounded to 8 bits, then interpolated again) was off by
    // up to half a level, and blurred detail a texel wide.
    CHECK(albedo->shift() == glm::vec2(1.5f));
    std::mt19937 g(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    double direct = 0;
    for (int k = 0; k < 2000; ++k) {
        const glm::dvec2 uv(u(g), u(g));
        const double want = detail::bilinearWrapped(uv.x * n + 1.5, uv.y * n + 1.5, n, n, [&](int i, int j) {
            return double(c.rgba[4 * (static_cast<std::size_t>(j) * n + static_cast<std::size_t>(i))]);
        });
        direct = std::max(direct, std::abs(255.0 * sampleMesoAlbedo<double>(*albedo, uv, 0.0).x - want));
    }
    INFO("largest difference from the image read 1.5 texels on: " << direct << " levels");
    CHECK(direct < 1e-9);
    // The header read: its size; a missing file or one that is not a PNG, a FileError.
    CHECK((readPngSize((dir.path / "h.png").string()).width == n && readPngSize((dir.path / "h.png").string()).height == n));
    CHECK_THROWS_AS(readPngSize((dir.path / "missing.png").string()), FileError);
    dmtest::writeBytes((dir.path / "text.png").string(), {'n', 'o', 't', ' ', 'a', ' ', 'p', 'n', 'g'});
    CHECK_THROWS_WITH(readPngSize((dir.path / "text.png").string()), Contains("not a PNG file"));
    // The shift by the colour image's size against the field's: half a texel less than half the
    // ratio. Nothing moves for a function's field or an image of the field's size.
    const auto shift = [&](const std::string& json, int w, int hgt) {
        return detail::mesoImageShift(parseMesoScene(nlohmann::json::parse(json), "s.json", dir.path.string()), w, hgt);
    };
    CHECK(shift(R"({"mesostructure": {"height": "h.png", "size": 16}})", 128, 32) == glm::dvec2(3.5, 0.5));
    CHECK(shift(R"({"mesostructure": {"height": "h.png", "size": 16}})", 16, 16) == glm::dvec2(0.0));
    CHECK(shift(R"({"mesostructure": {"height": "h.png", "size": 32}})", 16, 16) == glm::dvec2(-0.25));
    CHECK(shift(R"({"mesostructure": {"size": 16}})", n, n) == glm::dvec2(0.0));
    CHECK(shift(R"({"mesostructure": {"height": "h.png"}})", n, n) == glm::dvec2(0.0));
    // A 32 x 64 height image at "size" 32 is not filtered (its width): its field is 32 x 64.
    HeightImage tall;
    tall.width = 32;
    tall.height = 64;
    tall.values.assign(32 * 64, 0.5f);
    writeHeightPng16((dir.path / "tall.png").string(), tall);
    CHECK(shift(R"({"mesostructure": {"height": "tall.png", "size": 32}})", 32, 64) == glm::dvec2(0.0));
    CHECK(shift(R"({"mesostructure": {"height": "tall.png", "size": 32}})", 64, 128) == glm::dvec2(0.5));
}

} // namespace
} // namespace meso_albedo_test
