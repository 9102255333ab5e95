// A mesostructure's normal map (meso/albedo.h normalMapFromHeights, kern::dmNormalMapTangent,
// kern::dmFrameTangentNormal, meso/march.h sampleMesoNormal): the slopes a map of heights
// holds against closed forms, the OpenGL / DirectX green and glTF's scale, the frame's
// rotation and mirroring, float against double, the scene's "normals" keys (the plane's
// proportions checked against the marched field's own slopes), and bad inputs.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "dispmap/io/png.h"
#include "dispmap/meso/march.h"
#include "dispmap/scene/meso.h"
#include "test_files.h"
#include "test_support.h"

namespace meso_normals_test {
namespace {
using namespace dispmap;
using Catch::Contains;

constexpr double kPi = 3.14159265358979323846;

double degreesBetween(const glm::dvec3& a, const glm::dvec3& b) {
    return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) * 180.0 / kPi;
}

// v(s, t) = a sin(2 pi s) cos(4 pi t) over one tile, sampled at texel (x, y) = (s w, t h).
HeightImage waves(int w, int h, double a) {
    HeightImage img;
    img.width = w;
    img.height = h;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            img.values.push_back(static_cast<float>(a * std::sin(2 * kPi * x / w) * std::cos(4 * kPi * y / h)));
    return img;
}

TEST_CASE("a normal map of heights holds their slopes, green up", "[meso][normals]") {
    const int w = 64, h = 64;
    const double a = 0.1, slope = 1.5;
    const MesoAlbedo map = mesoAlbedo(w, h, normalMapFromHeights(waves(w, h, a), slope), false);
    double worst = 0, worstFlipped = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double s = double(x) / w, t = double(y) / h;
            const glm::dvec3 exact = glm::normalize(glm::dvec3(-slope * a * 2 * kPi * std::cos(2 * kPi * s) * std::cos(4 * kPi * t),
                                                               slope * a * 4 * kPi * std::sin(2 * kPi * s) * std::sin(4 * kPi * t), 1.0));
            // Texel (x, y) sits at (x / w, y / h): level 0 read there is the texel itself.
            worst = std::max(worst, degreesBetween(glm::dvec3(sampleMesoNormal<double>(map, {s, t}, 0, 1, -1)), exact));
            worstFlipped = std::max(worstFlipped, degreesBetween(glm::dvec3(sampleMesoNormal<double>(map, {s, t}, 0, 1, 1)), exact));
        }
    INFO("worst angle to the closed form " << worst << " deg (read as DirectX: " << worstFlipped << ")");
    // 8-bit rounding: half a step of 2 / 255 in each component, at most 0.39 deg; the central
    // difference's relative error (2 pi f / n)^2 / 6 is 0.6 % at f = 2 cycles over 64 texels,
    // of slopes up to 1.9: 0.3 deg.
    CHECK(worst < 0.7);
    CHECK(worstFlipped > 20); // the green convention matters
}

TEST_CASE("a normal map's texel reads as OpenGL or DirectX, scaled as glTF", "[meso][normals]") {
    const auto texel = [](double x, double y, double z) { return glm::dvec4((x + 1) / 2, (y + 1) / 2, (z + 1) / 2, 1.0); };
    const auto read = [](const glm::dvec4& c, double scale, double green) { return kern::dmNormalMapTangent<double>(c, scale, green); };
    CHECK(glm::length(read(texel(0.6, 0.0, 0.8), 1, -1) - glm::dvec3(0.6, 0.0, 0.8)) < 1e-15);
    CHECK(glm::length(read(texel(0.0, 0.6, 0.8), 1, -1) - glm::dvec3(0.0, -0.6, 0.8)) < 1e-15); // green up: towards t = 0
    CHECK(glm::length(read(texel(0.0, 0.6, 0.8), 1, 1) - glm::dvec3(0.0, 0.6, 0.8)) < 1e-15);
    CHECK(glm::length(read(texel(0.6, 0.0, 0.8), 0.5, -1) - glm::normalize(glm::dvec3(0.3, 0.0, 0.8))) < 1e-15);
    CHECK(read(texel(0.0, 0.0, 0.0), 1, -1) == glm::dvec3(0, 0, 1)); // an empty texel: unperturbed
    CHECK(read(texel(0.6, 0.0, 0.8), 0.0, -1) == glm::dvec3(0, 0, 1)); // scale 0: the flat surface
    // Float against double, for every 8-bit texel value of a random sample.
    std::mt19937 g(7);
    std::uniform_int_distribution<int> b(0, 255);
    double worst = 0;
    for (int i = 0; i < 2000; ++i) {
        const glm::dvec4 c(b(g) / 255.0, b(g) / 255.0, b(g) / 255.0, 1.0);
        worst = std::max(worst, glm::length(glm::dvec3(kern::dmNormalMapTangent<float>(glm::vec4(c), 1.3f, -1.0f)) - read(c, 1.3, -1)));
    }
    CHECK(worst < 1e-6); // a unit vector through a few float operations
}

TEST_CASE("a tangent-space normal turns with the frame, mirrored charts too", "[meso][normals]") {
    const glm::dvec3 nt = glm::normalize(glm::dvec3(0.3, -0.5, 0.8));
    // The plane's frame, at any tile size: the normal itself.
    CHECK(glm::length(kern::dmFrameTangentNormal<double>(nt, {0.5, 0, 0}, {0, 2.0, 0}, {0, 0, 1}) - nt) < 1e-15);
    // A rotated orthogonal frame: the rotated normal.
    const glm::dvec3 e1 = glm::normalize(glm::dvec3(1, 2, 3)), e2 = glm::normalize(glm::cross(e1, glm::dvec3(0, 0, 1)));
    const glm::dmat3 r(e1, e2, glm::cross(e1, e2)); // a rotation: orthonormal columns, right-handed
    const glm::dvec3 rotated = kern::dmFrameTangentNormal<double>(nt, r * glm::dvec3(3, 0, 0), r * glm::dvec3(0, 0.2, 0), r * glm::dvec3(0, 0, 1));
    CHECK(glm::length(rotated - r * nt) < 1e-14);
    // A mirrored chart (t runs along -y): the map's y follows t.
    CHECK(glm::length(kern::dmFrameTangentNormal<double>(nt, {1, 0, 0}, {0, -1, 0}, {0, 0, 1}) - glm::dvec3(nt.x, -nt.y, nt.z)) < 1e-15);
    // A sheared frame (pT not orthogonal to pS): x along pS, y along pT, each of unit length.
    const glm::dvec3 sheared = kern::dmFrameTangentNormal<double>(glm::dvec3(1, 0, 0), {2, 0, 0}, {1, 1, 0}, {0, 0, 1});
    CHECK(glm::length(sheared - glm::dvec3(1, 0, 0)) < 1e-15);
    const glm::dvec3 diagonal = kern::dmFrameTangentNormal<double>(glm::normalize(glm::dvec3(0, 1, 1)), {2, 0, 0}, {1, 1, 0}, {0, 0, 1});
    CHECK(glm::length(diagonal - glm::normalize(glm::dvec3(std::sqrt(0.5), std::sqrt(0.5), 1))) < 1e-15);
}

TEST_CASE("a scene's normal map from its heights has the marched field's slopes", "[meso][normals][scene]") {
    // "normals": "height" on a function scene: each texel's normal is the central difference
    // of the marched field in world units, with the renderer's voxels per unit on the plane,
    // (W / tile, H / tile, L / slab): an independent route to the same proportion.
    const MesoSceneDesc s = parseMesoScene(nlohmann::json::parse(R"({"mesostructure": {"function": "waves", "size": 32, "layers": 16,
        "normals": "height"}, "tile": 0.4, "slab": 0.1, "effects": {"mips": false}})"), "n.json", "");
    const auto map = buildMesoSceneNormals(s);
    REQUIRE(map);
    REQUIRE((map->width() == 32 && map->height() == 32 && map->levels() == 1));
    const MesoHeightField f = mesoFunctionField("waves", 32, 16);
    const glm::dvec3 vpu(32 / 0.4, 32 / 0.4, 16 / 0.1);
    double worst = 0, steepest = 0;
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x) {
            const double gx = 0.5 * (double(f.at(x + 1, y)) - double(f.at(x - 1, y))), gy = 0.5 * (double(f.at(x, y + 1)) - double(f.at(x, y - 1)));
            const glm::dvec3 n = glm::normalize(glm::dvec3(-gx * vpu.x / vpu.z, -gy * vpu.y / vpu.z, 1.0));
            steepest = std::max(steepest, degreesBetween(n, {0, 0, 1}));
            worst = std::max(worst, degreesBetween(glm::dvec3(sampleMesoNormal<double>(*map, {x / 32.0, y / 32.0}, 0, 1, -1)), n));
        }
    INFO("worst " << worst << " deg; the steepest normal leans " << steepest << " deg");
    CHECK(steepest > 20);
    CHECK(worst < 0.4); // 8-bit rounding of a unit vector: at most 0.39 deg
    // On a base the tile's width is the base's mean: a base whose tiles are 0.4 wide gives the
    // plane's map; one whose tiles are half as wide (a steeper map) does not.
    FrameMesh base;
    base.corners.assign(3, FrameVertex{});
    for (FrameVertex& v : base.corners) {
        v.pS = {0.3, 0.0, 0.0};
        v.pT = {0.0, 0.5, 0.0};
    }
    CHECK(base.meanTileWidth() == Approx(0.4));
    CHECK(buildMesoSceneNormals(s, &base)->words == map->words);
    for (FrameVertex& v : base.corners) v.pS = v.pT = {0.0, 0.2, 0.0};
    CHECK(buildMesoSceneNormals(s, &base)->words != map->words);
    const FrameMesh empty;
    CHECK_THROWS_WITH(buildMesoSceneNormals(s, &empty), Contains("the base has no tile width"));
}

TEST_CASE("a normal map from a larger height image sits on the filtered field's samples", "[meso][normals][scene]") {
    // A 128^2 16-bit image filtered to the 32^2 field: field sample i averages image texels
    // 4 i .. 4 i + 3, centred on 4 i + 1.5, and sits at s = i / 32, where the map's texel 4 i
    // sits; so that texel must hold the slope at 4 i + 1.5 (unshifted, the normals are up to
    // 8.3 deg off here). Heights times depth (12 of 16 layers) in voxels.
    dmtest::TempDir dir("dispmap_normals_");
    const auto v = [](double x, double y) { return 0.5 + 0.4 * std::sin(2 * kPi * 2 * x / 128) * std::cos(2 * kPi * y / 128); };
    HeightImage img;
    img.width = img.height = 128;
    for (int y = 0; y < 128; ++y)
        for (int x = 0; x < 128; ++x) img.values.push_back(static_cast<float>(v(x, y)));
    writeHeightPng16((dir.path / "h.png").string(), img);
    const MesoSceneDesc s = parseMesoScene(nlohmann::json::parse(R"({"mesostructure": {"height": "h.png", "size": 32, "layers": 16,
        "depth": 12, "normals": "height"}, "tile": 0.4, "slab": 0.1, "effects": {"mips": false}})"), "n.json", dir.path.string());
    const auto map = buildMesoSceneNormals(s);
    REQUIRE((map && map->width() == 128 && map->levels() == 1));
    const double slope = 12 * 0.1 / 16 / 0.4; // world height of v = 1 over a tile's width
    double worst = 0, steepest = 0;
    for (int j = 0; j < 32; ++j)
        for (int i = 0; i < 32; ++i) {
            const double x = 4 * i + 1.5, y = 4 * j + 1.5, e = 1e-4;
            const double ds = 128 * (v(x + e, y) - v(x - e, y)) / (2 * e), dt = 128 * (v(x, y + e) - v(x, y - e)) / (2 * e);
            const glm::dvec3 n = glm::normalize(glm::dvec3(-slope * ds, -slope * dt, 1.0));
            steepest = std::max(steepest, degreesBetween(n, {0, 0, 1}));
            worst = std::max(worst, degreesBetween(glm::dvec3(sampleMesoNormal<double>(*map, {i / 32.0, j / 32.0}, 0, 1, -1)), n));
        }
    INFO("worst " << worst << " deg; the steepest normal leans " << steepest << " deg");
    CHECK(steepest > 30);
    // 8-bit rounding (0.39 deg), the half-texel resampling's and the central difference's
    // smoothing of a wave 64 texels long (about 0.1 %), 16-bit heights.
    CHECK(worst < 0.5);
}

TEST_CASE("images one after the other are read from their own first word", "[meso][normals]") {
    // The renderer's image buffer: the albedo's words, then the normal map's (dmMesoImage's
    // `image`); read from there, the second image is itself.
    const auto pattern = [](int w, int h, int seed) {
        std::vector<std::uint8_t> px(4 * static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
        for (std::size_t i = 0; i < px.size(); ++i) px[i] = static_cast<std::uint8_t>((37 * i + 11 * static_cast<std::size_t>(seed)) % 256);
        return px;
    };
    const MesoAlbedo first = mesoAlbedo(5, 3, pattern(5, 3, 1)), second = mesoAlbedo(8, 6, pattern(8, 6, 2));
    MesoAlbedo both = first;
    both.words.insert(both.words.end(), second.words.begin(), second.words.end());
    kern::DmMesoMapsT<double> m;
    m.image = &both;
    std::mt19937 g(3);
    std::uniform_real_distribution<double> u(-3.0, 3.0);
    for (int i = 0; i < 200; ++i) {
        const glm::dvec2 uv(u(g), u(g));
        const double lod = std::abs(u(g));
        CHECK(kern::dmMesoImage<double>(m, static_cast<int>(first.words.size()), uv, lod) == sampleMesoAlbedo<double>(second, uv, lod));
        CHECK(kern::dmMesoImage<double>(m, 0, uv, lod) == sampleMesoAlbedo<double>(first, uv, lod));
    }
}

TEST_CASE("a mesostructure scene's normal-map keys", "[meso][normals][scene][inputs]") {
    dmtest::TempDir dir("dispmap_normals_");
    std::vector<std::uint8_t> px(4 * 8 * 4, 200);
    writeRgbaPng((dir.path / "n.png").string(), 8, 4, px.data());
    const auto scene = [&](const std::string& json) { return parseMesoScene(nlohmann::json::parse(json), "a.json", dir.path.string()); };
    const MesoSceneDesc s = scene(R"({"mesostructure": {"normals": "n.png", "normalScale": 0.5, "normalGreen": "down"}})");
    CHECK((s.normalScale == 0.5 && !s.normalGreenUp && !s.normalsFromHeight));
    const auto map = buildMesoSceneNormals(s);
    REQUIRE(map);
    CHECK((map->width() == 8 && map->height() == 4 && map->levels() == 4));
    CHECK_FALSE(buildMesoSceneNormals(scene(R"({"mesostructure": {}})")));
    CHECK(scene(R"({"mesostructure": {}})").normalGreenUp);
    CHECK_THROWS_WITH(scene(R"({"mesostructure": {"normals": 3}})"), Contains("'mesostructure.normals' must be a file name"));
    CHECK_THROWS_WITH(scene(R"({"mesostructure": {"normals": "n.png", "normalScale": 1e9}})"), Contains("'mesostructure.normalScale' 1e+09 is not within +-100"));
    CHECK_THROWS_WITH(scene(R"({"mesostructure": {"normals": "n.png", "normalGreen": "left"}})"), Contains("'mesostructure.normalGreen' must be \"up\""));
    CHECK_THROWS_WITH(scene(R"({"mesostructure": {"normalGreen": "up"}})"), Contains("'mesostructure.normalGreen' without 'mesostructure.normals'"));
    CHECK_THROWS_AS(buildMesoSceneNormals(scene(R"({"mesostructure": {"normals": "missing.png"}})")), FileError);
    // Heights from an image: at its full resolution, not the marched size.
    HeightImage big = waves(128, 128, 0.5);
    for (float& v : big.values) v = 0.5f + v;
    writeHeightPng16((dir.path / "h.png").string(), big);
    const auto fromImage = buildMesoSceneNormals(scene(R"({"mesostructure": {"height": "h.png", "size": 32, "normals": "height"}})"));
    REQUIRE(fromImage);
    CHECK((fromImage->width() == 128 && fromImage->levels() == 8));
}

TEST_CASE("bad normal-map inputs are clear errors", "[meso][normals][inputs]") {
    CHECK_THROWS_WITH(normalMapFromHeights(HeightImage{}, 1.0), Contains("height image of 0 x 0 texels"));
    HeightImage img = waves(4, 4, 0.1);
    CHECK_THROWS_WITH(normalMapFromHeights(img, std::nan("")), Contains("the slope is not finite"));
    img.values[5] = std::numeric_limits<float>::infinity();
    CHECK_THROWS_WITH(normalMapFromHeights(img, 1.0), Contains("a value that is not finite"));
    img.values.pop_back();
    CHECK_THROWS_WITH(normalMapFromHeights(img, 1.0), Contains("with its values"));
    const MesoAlbedo map = mesoAlbedo(2, 2, std::vector<std::uint8_t>(16, 128));
    CHECK_THROWS_WITH(sampleMesoNormal<float>(map, {0, 0}, 0, 1, 0.5), Contains("greenT +1 or -1"));
    CHECK_THROWS_WITH(sampleMesoNormal<float>(map, {0, 0}, 0, std::nan(""), 1), Contains("greenT +1 or -1"));
}

TEST_CASE("height images whose size the field's does not divide: all of the image, area-weighted", "[meso][normals][inputs]") {
    // Until 2026-12-04 the box filter took width / size texels a sample (integer division) and
    // cut the remainder: a 100-wide image at size 32 lost its last 4 columns, and the field
    // no longer lined up with an albedo over the whole tile. Reference: the same image with every
    // texel repeated 8 x 8 times, filtered with whole blocks (800 / 32 = 25, 576 / 32 = 18),
    // whose block means are the area-weighted means of the original.
    HeightImage img;
    img.width = 100;
    img.height = 72;
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    for (int i = 0; i < img.width * img.height; ++i) img.values.push_back(U(rng));
    HeightImage fine;
    fine.width = 8 * img.width;
    fine.height = 8 * img.height;
    for (int y = 0; y < fine.height; ++y)
        for (int x = 0; x < fine.width; ++x) fine.values.push_back(img.at(x / 8, y / 8));
    const HeightImage a = downsampleHeightImage(img, 32), b = downsampleHeightImage(fine, 32);
    REQUIRE((a.width == 32 && a.height == 32 && b.width == 32));
    double worst = 0;
    for (std::size_t i = 0; i < a.values.size(); ++i) worst = std::max(worst, std::abs(double(a.values[i]) - double(b.values[i])));
    // Both round a mean of values in [0, 1] to float once (6e-8), their sums in another order.
    CHECK(worst < 2e-7);
    // The last column and row read the image's last texels (they were cut before).
    HeightImage edge = img;
    for (int y = 0; y < edge.height; ++y) edge.values[std::size_t(y * edge.width + edge.width - 1)] += 1.0f;
    CHECK(downsampleHeightImage(edge, 32).at(31, 5) > a.at(31, 5) + 0.1f);
    // A constant image stays constant.
    HeightImage flat;
    flat.width = 77;
    flat.height = 45;
    flat.values.assign(77 * 45, 0.625f);
    const HeightImage flatSmall = downsampleHeightImage(flat, 16);
    for (float v : flatSmall.values) CHECK(v == Approx(0.625).epsilon(1e-6));
    // The normal map made from the heights covers the same image, whole.
    const HeightImage aligned = fieldAlignedHeightImage(img, 32);
    CHECK((aligned.width == 100 && aligned.height == 72));
    const HeightImage flatAligned = fieldAlignedHeightImage(flat, 16);
    for (float v : flatAligned.values) CHECK(v == Approx(0.625).epsilon(1e-6));
    // Sizes out of range are refused, as before.
    CHECK_THROWS_WITH(downsampleHeightImage(img, 73), Contains("is smaller"));
    CHECK_THROWS_WITH(fieldAlignedHeightImage(img, 101), Contains("is smaller"));
    CHECK_THROWS_WITH(downsampleHeightImage(img, 1), Contains("below 2"));
}

} // namespace
} // namespace meso_normals_test
