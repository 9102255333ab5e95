// The traditional baseline (baseline.h, kernels/baseline.h): the tangent frame and its
// encode/decode round trip (double, float, 8-bit), the atlas layout, texels shared along every
// edge (and the T-junction rule), holes, bad sizes; and the RGBA PNG files of height_image.h.
#include <catch2/catch.hpp>

#include "test_files.h"
#include "test_support.h"

#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <png.h>

#include "dispmap/surface/baseline.h"
#include "dispmap/surface/map_source.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/io/png.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_baseline {

using namespace dispmap;

namespace {
struct TempDir : dmtest::TempDir {
    TempDir() : dmtest::TempDir("dispmap_baseline_test_") {}
};

glm::dvec3 randomUnit(std::mt19937_64& rng) {
    std::normal_distribution<double> g;
    for (;;) {
        const glm::dvec3 v(g(rng), g(rng), g(rng));
        if (glm::length(v) > 1e-3) return glm::normalize(v);
    }
}

double angle(const glm::dvec3& a, const glm::dvec3& b) {
    return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}

// What a shader reads from the normal map through a UNORM view: bytes / 255, unpacked.
glm::dvec3 unpack(const BaselineAtlas& a, std::size_t texel) {
    const glm::dvec3 c(a.normals[4 * texel] / 255.0, a.normals[4 * texel + 1] / 255.0, a.normals[4 * texel + 2] / 255.0);
    return kern::dmUnpackUnormNormal(c);
}

// Texel m (0..n) along tile edge e (edge parameter m / n, the convention of TileTopology).
std::size_t edgeTexel(const BaselineAtlas& a, int face, int e, int m) {
    const int n = a.texelsPerFace;
    const int i = e == 0 ? m : e == 1 ? n : e == 2 ? n - m : 0;
    const int j = e == 0 ? 0 : e == 1 ? m : e == 2 ? n : n - m;
    return a.chartIndex(face, i, j);
}

// The baked scene: the default box (valence 3 and 5, a pentagon, a triangle: T-junctions).
struct Baked {
    ControlMesh mesh = builtin::defaultMesh();
    TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 4), builtin::defaultDisplacement);
    BaseSurface base{mesh};
    DisplacedSurface surface{base, tiles};
};

// Half the largest angle between a unit vector and one whose components are each off by at
// most 1/255 (8-bit UNORM storage of n/2 + 1/2 rounds to 0.5/255, times 2 when unpacked):
// |error| <= sqrt(3)/255, so the angle is at most asin(sqrt(3)/255).
const double kQuantAngle = std::asin(std::sqrt(3.0) / 255.0);
} // namespace

TEST_CASE("baseline: tangent frame and encode/decode round trip", "[baseline]") {
    std::mt19937_64 rng(20130601);
    double worst8 = 0, worstD = 0, worstF = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        const glm::dvec3 N = randomUnit(rng);
        glm::dvec3 su = randomUnit(rng) * std::exp(std::uniform_real_distribution<double>(-5, 5)(rng));
        if (trial % 100 == 0) su = glm::dvec3(0);      // degenerate: zero derivative
        if (trial % 100 == 1) su = N * 3.0;            // degenerate: parallel to N
        const glm::dvec3 T = kern::dmTangentFromDerivative(su, N);
        CHECK(glm::length(T) == Approx(1.0).margin(1e-14));
        CHECK(std::abs(glm::dot(T, N)) < 1e-14);
        if (trial % 100 > 1) CHECK(glm::dot(T, su) > 0.0);
        const glm::dvec3 n = randomUnit(rng);
        // Double: exact to rounding; the frame is orthonormal, so the encoding is unit length.
        const glm::dvec3 nts = kern::dmTangentSpaceEncode(n, T, N);
        CHECK(glm::length(nts) == Approx(1.0).margin(1e-14));
        const glm::dvec3 back = kern::dmTangentSpaceDecode(nts, T, N);
        worstD = std::max(worstD, glm::length(back - n));
        // Float.
        const glm::vec3 Tf(T), Nf(N), nf(n);
        const glm::vec3 backF = kern::dmTangentSpaceDecode(kern::dmTangentSpaceEncode(nf, Tf, Nf), Tf, Nf);
        worstF = std::max(worstF, glm::length(glm::dvec3(backF) - n));
        // 8-bit, as the atlas stores it and a UNORM view reads it.
        glm::dvec3 c;
        for (int i = 0; i < 3; ++i) c[i] = double(std::clamp(std::lround((0.5 * nts[i] + 0.5) * 255.0), 0l, 255l)) / 255.0;
        const glm::dvec3 back8 = kern::dmTangentSpaceDecode(kern::dmUnpackUnormNormal(c), T, N);
        worst8 = std::max(worst8, angle(back8, n));
    }
    CHECK(worstD < 1e-12);
    CHECK(worstF < 1e-5);
    CHECK(worst8 <= kQuantAngle);
    CHECK(worst8 > 0.25 * kQuantAngle); // the bound is not loose by much
    // A zero encoding decodes to N; the frame's own axes decode to themselves.
    const glm::dvec3 N(0, 0, 1), T = kern::dmTangentFromDerivative(glm::dvec3(2, 0, 1), N);
    CHECK(T == glm::dvec3(1, 0, 0));
    CHECK(kern::dmTangentSpaceDecode(glm::dvec3(0), T, N) == N);
    CHECK(kern::dmTangentSpaceDecode(glm::dvec3(0, 1, 0), T, N) == glm::dvec3(0, 1, 0));
    CHECK(kern::dmTangentSpaceEncode(glm::dvec3(0, 1, 0), T, N) == glm::dvec3(0, 1, 0));
    // Degenerate su with N along x: the fallback axis is y.
    CHECK(kern::dmTangentFromDerivative(glm::dvec3(0), glm::dvec3(1, 0, 0)) == glm::dvec3(0, 1, 0));
}

TEST_CASE("baseline: atlas layout, texel values and sizes", "[baseline]") {
    const Baked b;
    const int n = 8;
    const BaselineAtlas a = bakeBaseline(b.surface, n);
    const int faces = b.base.faceCount();
    REQUIRE(faces == 21);
    CHECK(a.texelsPerFace == n);
    CHECK(a.width == 5 * (n + 1)); // 5 x 5 grid of charts for 21 faces
    CHECK(a.height == 5 * (n + 1));
    CHECK(a.heights.size() == std::size_t(a.width * a.height));
    CHECK(a.normals.size() == 4 * a.heights.size());
    CHECK(a.bytes() == std::size_t(a.width * a.height) * 8);
    REQUIRE(a.chartOrigins.size() == std::size_t(faces));
    std::set<std::pair<unsigned, unsigned>> origins;
    for (const glm::uvec2& o : a.chartOrigins) {
        origins.insert({o.x, o.y});
        CHECK(o.x % (n + 1) == 0);
        CHECK(o.y % (n + 1) == 0);
        CHECK(o.x + unsigned(n) < unsigned(a.width));
        CHECK(o.y + unsigned(n) < unsigned(a.height));
    }
    CHECK(origins.size() == std::size_t(faces));
    // The shader's texture coordinate of (u, v) = (i, j) / n is the texel centre.
    for (int f : {0, 7, 20}) {
        const glm::dvec2 o(a.chartOrigins[std::size_t(f)]);
        const glm::dvec2 uv = kern::dmBaselineAtlasUV(o, glm::dvec2(3.0 / n, 1.0), double(n), glm::dvec2(a.width, a.height));
        CHECK(uv.x * a.width == Approx(o.x + 3 + 0.5).epsilon(1e-14));
        CHECK(uv.y * a.height == Approx(o.y + n + 0.5).epsilon(1e-14));
    }
    // Texels away from T-junction edges hold D and the encoded accurate normal at their point.
    double worstNormal = 0;
    for (int f = 0; f < faces; ++f)
        for (int j = 1; j < n; ++j)
            for (int i = 1; i < n; ++i) {
                const double u = double(i) / n, v = double(j) / n;
                const SurfaceSample<double> s = b.surface.evaluate<double>(f, u, v, NormalMode::Accurate);
                const std::size_t at = a.chartIndex(f, i, j);
                CHECK(a.heights[at] == static_cast<float>(s.displacement.x));
                CHECK(a.normals[4 * at + 3] == 255);
                const glm::dvec3 T = kern::dmTangentFromDerivative(b.base.evaluate<double>(f, u, v, false).du, s.baseNormal);
                worstNormal = std::max(worstNormal, angle(kern::dmTangentSpaceDecode(unpack(a, at), T, s.baseNormal), s.normal));
            }
    CHECK(worstNormal <= kQuantAngle);
    // Texels outside every chart stay zero.
    std::vector<std::uint8_t> used(a.heights.size(), 0);
    for (int f = 0; f < faces; ++f)
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) used[a.chartIndex(f, i, j)] = 1;
    for (std::size_t t = 0; t < used.size(); ++t)
        if (!used[t]) {
            CHECK(a.heights[t] == 0.0f);
            CHECK(a.normals[4 * t + 3] == 0);
        }
    // n = 1: one texel per corner.
    const BaselineAtlas one = bakeBaseline(b.surface, 1);
    CHECK(one.width == 10);
    CHECK(one.height == 10);
    CHECK(one.heights[one.chartIndex(4, 1, 1)] ==
          static_cast<float>(b.surface.evaluate<double>(4, 1.0, 1.0, NormalMode::Accurate).displacement.x));
}

TEST_CASE("baseline: both faces of an edge hold the same surface points", "[baseline]") {
    const Baked b;
    const TileTopology& topo = b.base.topology();
    for (int n : {5, 8}) {
        CAPTURE(n);
        const BaselineAtlas a = bakeBaseline(b.surface, n);
        double worstD = 0, worstTexel = 0, worstNormal = 0, worstT = 0;
        int equalLinks = 0, tLinks = 0;
        for (int t = 0; t < topo.tileCount(); ++t)
            for (int e = 0; e < 4; ++e)
                for (const TileTopology::Link& l : topo.links(t, e)) {
                    if (l.beta == 1.0) {
                        ++equalLinks;
                        for (int m = 0; m <= n; ++m) {
                            const int mb = static_cast<int>(std::lround(l.alpha * n)) - m; // z = alpha - y
                            REQUIRE(mb >= 0);
                            REQUIRE(mb <= n);
                            const glm::dvec2 pa = dmtest::edgePoint(e, double(m) / n);
                            const glm::dvec2 pb = dmtest::edgePoint(l.edge, double(mb) / n);
                            const SurfaceSample<double> sa = b.surface.evaluate<double>(t, pa.x, pa.y, NormalMode::Accurate);
                            const SurfaceSample<double> sb = b.surface.evaluate<double>(l.tile, pb.x, pb.y, NormalMode::Accurate);
                            // The same surface point (size of the box: 2), the same D.
                            REQUIRE(glm::length(sa.position - sb.position) < 1e-9);
                            worstD = std::max(worstD, std::abs(sa.displacement.x - sb.displacement.x));
                            const float ha = a.heights[edgeTexel(a, t, e, m)], hb = a.heights[edgeTexel(a, l.tile, l.edge, mb)];
                            worstTexel = std::max(worstTexel, double(std::abs(ha - hb)));
                            // Decoded in each face's own frame, the normal maps agree to quantisation
                            // (plus the accurate normal's own difference across the edge).
                            const glm::dvec3 Ta = kern::dmTangentFromDerivative(
                                b.base.evaluate<double>(t, pa.x, pa.y, false).du, sa.baseNormal);
                            const glm::dvec3 Tb = kern::dmTangentFromDerivative(
                                b.base.evaluate<double>(l.tile, pb.x, pb.y, false).du, sb.baseNormal);
                            const glm::dvec3 na = kern::dmTangentSpaceDecode(unpack(a, edgeTexel(a, t, e, m)), Ta, sa.baseNormal);
                            const glm::dvec3 nb =
                                kern::dmTangentSpaceDecode(unpack(a, edgeTexel(a, l.tile, l.edge, mb)), Tb, sb.baseNormal);
                            worstNormal = std::max(worstNormal, angle(na, nb) - angle(sa.normal, sb.normal));
                            worstT = std::max(worstT, angle(sa.normal, sb.normal));
                        }
                    } else if (l.beta == 0.5) {
                        // T-junction, sub-face side: its edge reads, bilinearly, what the quad's does.
                        ++tLinks;
                        for (int i = 0; i <= 64; ++i) {
                            const double y = i / 64.0, z = l.alpha - l.beta * y;
                            const glm::dvec2 pa = dmtest::edgePoint(e, y), pb = dmtest::edgePoint(l.edge, z);
                            const double ha = sampleBaselineHeight(a, t, pa.x, pa.y);
                            const double hb = sampleBaselineHeight(a, l.tile, pb.x, pb.y);
                            CHECK(std::abs(ha - hb) < 1e-8);
                        }
                    }
                }
        CHECK(equalLinks > 0);
        CHECK(tLinks > 0);
        CHECK(worstD < 1e-12);
        CHECK(worstTexel <= 1e-7); // the same double D rounded to float, up to an ULP (|D| < 0.1)
        CHECK(worstNormal <= 2 * kQuantAngle);
        INFO("accurate normal differs across edges by up to " << worstT << " rad");
        CHECK(worstT < 1e-3);
    }
}

TEST_CASE("baseline: holes and bad sizes", "[baseline]") {
    const ControlMesh mesh = dmtest::shape("catmark_hole_test1");
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 3), dmtest::roughSource);
    const BaseSurface base(mesh);
    const DisplacedSurface surface(base, tiles);
    const int n = 4;
    const BaselineAtlas a = bakeBaseline(surface, n);
    int holes = 0;
    for (int f = 0; f < base.faceCount(); ++f) {
        if (!base.isHole(f)) continue;
        ++holes;
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) {
                const std::size_t at = a.chartIndex(f, i, j);
                CHECK(a.heights[at] == 0.0f);
                CHECK(a.normals[4 * at] == 128);
                CHECK(a.normals[4 * at + 1] == 128);
                CHECK(a.normals[4 * at + 2] == 255);
                CHECK(a.normals[4 * at + 3] == 255);
            }
    }
    CHECK(holes > 0);

    const Baked b;
    CHECK_THROWS_AS(bakeBaseline(b.surface, 0), ArgumentError);
    CHECK_THROWS_AS(bakeBaseline(b.surface, -3), ArgumentError);
    CHECK_THROWS_AS(bakeBaseline(b.surface, 1025), ArgumentError);
    // 300 faces need 18 columns: 18 x 1025 texels is over 16384 (refused before any work).
    const ControlMesh big = builtin::torusCage(20, 15, 3.0, 1.0, "big torus");
    const TileSet bigTiles = buildTiles(big, uniformTileSizes(big, 1), [](int, double, double) { return 0.0; });
    const BaseSurface bigBase(big);
    const DisplacedSurface bigSurface(bigBase, bigTiles);
    CHECK_THROWS_WITH(bakeBaseline(bigSurface, 1024), Catch::Contains("18450 x") && Catch::Contains("at most 16384"));
    CHECK_THROWS_AS(sampleBaselineHeight(bakeBaseline(b.surface, 2), 21, 0.5, 0.5), ArgumentError);
    CHECK_THROWS_AS(sampleBaselineHeight(bakeBaseline(b.surface, 2), 0, 1.5, 0.5), ArgumentError);
}

TEST_CASE("RGBA PNG: round trip, converted inputs, bad files", "[baseline][png]") {
    TempDir dir;
    const std::string path = dir.file("c.png");
    std::vector<std::uint8_t> px(7 * 5 * 4);
    for (std::size_t i = 0; i < px.size(); ++i) px[i] = static_cast<std::uint8_t>((i * 7919 + 13) % 256);
    writeRgbaPng(path, 7, 5, px.data());
    const RgbaImage img = readRgbaPng(path);
    CHECK(img.width == 7);
    CHECK(img.height == 5);
    CHECK(img.rgba == px);
    CHECK(dir.entries() == std::set<std::string>{"c.png"}); // no temporary left

    // Grey, grey + alpha, RGB files (written by libpng's simplified API).
    const std::vector<std::uint8_t> grey = {0, 50, 100, 150, 200, 255};
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    image.width = 3;
    image.height = 2;
    image.format = PNG_FORMAT_GRAY;
    REQUIRE(png_image_write_to_file(&image, dir.file("g.png").c_str(), 0, grey.data(), 0, nullptr) != 0);
    const RgbaImage g = readRgbaPng(dir.file("g.png"));
    REQUIRE(g.rgba.size() == 24);
    for (std::size_t i = 0; i < 6; ++i) {
        CHECK(g.rgba[4 * i] == grey[i]);
        CHECK(g.rgba[4 * i + 1] == grey[i]);
        CHECK(g.rgba[4 * i + 2] == grey[i]);
        CHECK(g.rgba[4 * i + 3] == 255);
    }
    const std::vector<std::uint8_t> rgb = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18};
    image = png_image{};
    image.version = PNG_IMAGE_VERSION;
    image.width = 3;
    image.height = 2;
    image.format = PNG_FORMAT_RGB;
    REQUIRE(png_image_write_to_file(&image, dir.file("rgb.png").c_str(), 0, rgb.data(), 0, nullptr) != 0);
    const RgbaImage c = readRgbaPng(dir.file("rgb.png"));
    REQUIRE(c.rgba.size() == 24);
    for (std::size_t i = 0; i < 6; ++i) {
        for (std::size_t k = 0; k < 3; ++k) CHECK(c.rgba[4 * i + k] == rgb[3 * i + k]);
        CHECK(c.rgba[4 * i + 3] == 255);
    }

    // Missing, truncated, not a PNG.
    CHECK_THROWS_WITH(readRgbaPng(dir.file("missing.png")), Catch::Contains("missing.png"));
    CHECK_THROWS_AS(readRgbaPng(dir.file("missing.png")), FileError);
    std::vector<unsigned char> bytes = dmtest::readBytes(path);
    bytes.resize(bytes.size() / 2);
    dmtest::writeBytes(dir.file("cut.png"), bytes);
    CHECK_THROWS_WITH(readRgbaPng(dir.file("cut.png")), Catch::Contains("cut.png") && Catch::Contains("truncated"));
    CHECK_THROWS_AS(readRgbaPng(dir.file("cut.png")), FileError);
    dmtest::writeBytes(dir.file("text.png"), {'h', 'e', 'l', 'l', 'o'});
    CHECK_THROWS_WITH(readRgbaPng(dir.file("text.png")), Catch::Contains("not a PNG"));

    // Bad sizes and pointers write nothing; an unwritable path is a FileError.
    CHECK_THROWS_AS(writeRgbaPng(dir.file("z.png"), 0, 5, px.data()), ArgumentError);
    CHECK_THROWS_AS(writeRgbaPng(dir.file("z.png"), 7, -1, px.data()), ArgumentError);
    CHECK_THROWS_AS(writeRgbaPng(dir.file("z.png"), 7, 5, nullptr), ArgumentError);
    CHECK_THROWS_AS(writeRgbaPng(dir.file("no/such/dir/z.png"), 7, 5, px.data()), FileError);
    CHECK(!std::filesystem::exists(dir.file("z.png")));
}

} // namespace dmtest_baseline

namespace dmtest_baseline {
namespace {

// Spot with the brick map on its UVs (smooth), 2^4 tiles: a real UV layout with seams.
struct SpotBricks {
    ControlMesh mesh = dmtest::shape("spot_control_mesh");
    std::shared_ptr<const UvMap> smooth = std::make_shared<const UvMap>(mesh, UvInterpolation::Smooth);
    UvMap linear{mesh, UvInterpolation::Linear};
    TileSet tiles = build();
    BaseSurface base{mesh};
    DisplacedSurface surface{base, tiles};

    TileSet build() const {
        HeightMaps brick;
        brick.images[0] = std::make_shared<const HeightImage>(readHeightPng(dmtest::dataPath("skimage_brick.png")));
        MapSourceOptions o;
        o.allowOverlap = true;
        o.filter = MapFilter::Box;
        o.scale = 0.02;
        const std::vector<int> k = uniformTileSizes(mesh, 4);
        return buildTiles(mesh, k, mapSource(smooth, brick, k, o));
    }
};

} // namespace

TEST_CASE("baseline on the mesh's UVs: texel centres hold the surface, UV seams crack, chart interiors do not", "[baseline]") {
    const SpotBricks spot;
    const int size = 256;
    const BaselineAtlas a = bakeBaselineUv(spot.surface, spot.linear, size, size);
    REQUIRE(a.layout == BaselineLayout::MeshUv);
    REQUIRE(a.faceCount() == spot.base.faceCount());

    // Texel centres strictly inside a face (rasterised again) that no other face (nor a
    // repeated copy) covers: the lookup reads that texel alone (the texture coordinate is the
    // centre), so it returns the surface's D in float, and the normal map decodes in
    // the same frame the bake encoded in: within the 8-bit quantisation angle.
    std::vector<int> tiles(static_cast<std::size_t>(spot.base.faceCount()), 0);
    std::vector<int> writes(static_cast<std::size_t>(size * size), 0);
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
            rasterizeUvs(spot.linear, tiles, 0, size, size, 4, 0.0, 0,
                         [&](int x, int y, int, double, double) { ++writes[static_cast<std::size_t>(y * size + x)]; }, glm::dvec2(dx, dy));
    double dMax = 0.0, dErr = 0.0, nErr = 0.0;
    int visits = 0, shared = 0;
    rasterizeUvs(spot.linear, tiles, 0, size, size, 4, 0.02, 3, [&](int x, int y, int t, double u, double v) {
        if (writes[static_cast<std::size_t>(y * size + x)] != 1) {
            ++shared;
            return;
        }
        if (++visits % 7) return;
        const SurfaceSample<double> s = spot.surface.evaluate<double>(t, u, v, NormalMode::Accurate);
        const BaseSample<double> b = spot.base.evaluate<double>(t, u, v, false);
        dMax = std::max(dMax, std::abs(s.displacement.x));
        dErr = std::max(dErr, std::abs(sampleBaselineHeight(a, t, u, v) - s.displacement.x));
        nErr = std::max(nErr, angle(sampleBaselineNormal(a, t, u, v, b.du, s.baseNormal), s.normal));
    });
    INFO(visits << " texel centres (" << shared << " covered twice), max |D| " << dMax << ", height error " << dErr
                 << ", normal error " << nErr);
    REQUIRE(visits > 15000);
    // The corner UVs are stored as float: the coordinate lands within ~2^-24 * 256 = 1.5e-5 texel
    // of the centre, which mixes in that much of a neighbour (differing by less than 2 max |D|).
    CHECK(dErr < 3e-5 * dMax);
    CHECK(nErr < kQuantAngle + 1e-6);

    // Both sides of every edge: inside a chart they read the same texels at the same texture
    // coordinate in the same frame; across a UV seam they read different charts.
    const UvSeamReport uv = measureUvSeams(spot.surface, spot.linear, &a);
    const UvSeamReport ours = measureUvSeams(spot.surface, spot.linear, nullptr);
    const BaselineAtlas faces = bakeBaseline(spot.surface, 16);
    const UvSeamReport perFace = measureUvSeams(spot.surface, spot.linear, &faces);
    INFO("uv: seams " << uv.seams.points << " points, gap " << uv.seams.maxGap << " (mean " << uv.seams.meanGap << "), jump "
                      << uv.seams.maxJump << " (mean " << uv.seams.meanJump << "); inside gap " << uv.inside.maxGap << ", jump "
                      << uv.inside.maxJump << "; ours: seams gap " << ours.seams.maxGap << " jump " << ours.seams.maxJump
                      << "; faces: seams gap " << perFace.seams.maxGap << " jump " << perFace.seams.maxJump);
    REQUIRE(uv.seams.points > 500);
    REQUIRE(uv.inside.points > 5000);
    CHECK(uv.seams.meanGap > 1e-4);       // cracks: measured 1e-3 of the mesh size on average
    CHECK(uv.inside.maxGap < 1e-6);       // corner UVs in float: the two faces' texture coordinates differ by rounding
    CHECK(uv.seams.meanJump > 0.05);      // shading seams: measured ~0.2 rad on average
    CHECK(uv.inside.maxJump < 1e-3);      // the same corner tangents on both sides: float rounding of the frame
    CHECK(ours.seams.maxGap < 1e-9);      // dispmap: the tiles share their edges (double evaluation)
    CHECK(ours.seams.maxJump < 1e-6);
    CHECK(perFace.seams.maxGap < 1e-6);   // the seam-free atlas: both charts hold the same points
}

TEST_CASE("baseline on the mesh's UVs: gutters, bad input", "[baseline]") {
    const SpotBricks spot;
    // Gutters: a texel no face covers but next to covered ones holds the mean of their heights
    // after the first round; without a gutter it keeps 0. The measured effect on the seams
    // is in docs/figures.md (on this map the gutter widens the cracks: its texels continue each
    // chart's border, where an empty texel pulls D towards 0 = the mid-level).
    const int size = 128;
    const BaselineAtlas bare = bakeBaselineUv(spot.surface, spot.linear, size, size, 0);
    const BaselineAtlas padded = bakeBaselineUv(spot.surface, spot.linear, size, size, 4);
    std::vector<int> tiles(static_cast<std::size_t>(spot.base.faceCount()), 0);
    std::vector<char> covered(static_cast<std::size_t>(size * size), 0);
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
            rasterizeUvs(spot.linear, tiles, 0, size, size, 4, 0.0, 0,
                         [&](int x, int y, int, double, double) { covered[static_cast<std::size_t>(y * size + x)] = 1; }, glm::dvec2(dx, dy));
    int ring = 0, far = 0;
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const std::size_t at = static_cast<std::size_t>(y * size + x);
            if (covered[at]) {
                CHECK(bare.heights[at] == padded.heights[at]);
                continue;
            }
            CHECK(bare.heights[at] == 0.0f);
            double sum = 0.0;
            int count = 0;
            for (int j = -1; j <= 1; ++j)
                for (int i = -1; i <= 1; ++i) {
                    const std::size_t o = static_cast<std::size_t>(((y + j + size) % size) * size + (x + i + size) % size);
                    if (covered[o]) {
                        sum += static_cast<double>(padded.heights[o]);
                        ++count;
                    }
                }
            if (count > 0) {
                ++ring;
                CHECK(std::abs(static_cast<double>(padded.heights[at]) - sum / count) < 1e-7);
            } else {
                ++far;
            }
        }
    INFO(ring << " texels next to the charts, " << far << " farther");
    CHECK(ring > 100);
    CHECK(far > 100);

    CHECK_THROWS_WITH(bakeBaselineUv(spot.surface, *spot.smooth, 64, 64), Catch::Contains("linearly"));
    CHECK_THROWS_WITH(bakeBaselineUv(spot.surface, spot.linear, 0, 64), Catch::Contains("out of range"));
    CHECK_THROWS_WITH(bakeBaselineUv(spot.surface, spot.linear, 64, 16385), Catch::Contains("out of range"));
    CHECK_THROWS_WITH(bakeBaselineUv(spot.surface, spot.linear, 64, 64, -1), Catch::Contains("gutter"));
    CHECK_THROWS_WITH(bakeBaselineUv(spot.surface, spot.linear, 64, 64, 65), Catch::Contains("gutter"));
    const Baked box;
    CHECK_THROWS_WITH(bakeBaselineUv(box.surface, spot.linear, 64, 64), Catch::Contains("ptex faces"));
    // UVs in the next UDIM tile (1002): one repeating tile only.
    MeshDescription d = parseObj(dmtest::gridObj(3, 3), "shifted grid");
    for (glm::dvec2& t : d.uvs) t.x += 1.0;
    const ControlMesh shifted(d);
    const TileSet flat = buildTiles(shifted, uniformTileSizes(shifted, 2), [](int, double, double) { return 0.0; });
    const BaseSurface shiftedBase(shifted);
    const DisplacedSurface shiftedSurface(shiftedBase, flat);
    CHECK_THROWS_WITH(bakeBaselineUv(shiftedSurface, UvMap(shifted, UvInterpolation::Linear), 64, 64),
                      Catch::Contains("outside the UV square") && Catch::Contains("ptex face 0"));
    // A layout without overlaps shares no texel; Spot's shells reach past the square onto
    // other charts (its UVs leave [0, 1]^2 by 5 %).
    const ControlMesh gridMesh(parseObj(dmtest::gridObj(4, 4), "grid"));
    const TileSet gridTiles = buildTiles(gridMesh, uniformTileSizes(gridMesh, 2), [](int, double, double) { return 0.0; });
    const BaseSurface gridBase(gridMesh);
    const DisplacedSurface gridSurface(gridBase, gridTiles);
    CHECK(bakeBaselineUv(gridSurface, UvMap(gridMesh, UvInterpolation::Linear), 64, 64).sharedTexels == 0);
    CHECK(padded.sharedTexels > 0);
    const BaselineAtlas a = bakeBaselineUv(spot.surface, spot.linear, 32, 32);
    CHECK_THROWS_AS(sampleBaselineNormal(a, -1, 0.5, 0.5, glm::dvec3(1, 0, 0), glm::dvec3(0, 0, 1)), ArgumentError);
    CHECK_THROWS_AS(sampleBaselineHeight(a, a.faceCount(), 0.5, 0.5), ArgumentError);
    CHECK_THROWS_AS(sampleBaselineHeight(a, 0, 0.5, -0.1), ArgumentError);
    CHECK(parseBaselineLayout("uv") == BaselineLayout::MeshUv);
    CHECK(parseBaselineLayout("faces") == BaselineLayout::Faces);
    CHECK_FALSE(parseBaselineLayout("atlas"));
}

} // namespace dmtest_baseline
