// Mesostructure maps and marchers: exact distance transforms against brute force,
// conservativeness of the directional maps, lossless compression, quadrics against their
// patches, the root solver against long double, every marcher on hard cases, bad inputs.
#include <catch2/catch.hpp>

#include <random>

#include "dispmap/io/meso_file.h"
#include "dispmap/meso/solid.h"
#include "test_meso_support.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_meso {

using namespace dispmap;
using dmtest::mesoField;

TEST_CASE("FH 1D transform equals brute force, with +Inf and spacing", "[meso][edt]") {
    std::mt19937 rng(7);
    const double inf = std::numeric_limits<double>::infinity();
    for (int trial = 0; trial < 300; ++trial) {
        const int n = 1 + trial % 23;
        const double w2 = trial % 3 == 0 ? 1.0 : trial % 3 == 1 ? 0.25 : 6.25;
        std::vector<double> f(static_cast<std::size_t>(n)), d(f.size()), z(f.size() + 1);
        std::vector<int> v(f.size());
        for (double& x : f) {
            const int r = static_cast<int>(rng() % 5);
            x = r == 0 ? inf : static_cast<double>(rng() % 40) * (r == 1 ? 0.0 : 0.5);
        }
        distanceTransform1D(f.data(), n, w2, d.data(), v.data(), z.data());
        for (int q = 0; q < n; ++q) {
            double best = inf;
            for (int p = 0; p < n; ++p) best = std::min(best, w2 * (q - p) * (q - p) + f[static_cast<std::size_t>(p)]);
            INFO("n " << n << " q " << q);
            CHECK(d[static_cast<std::size_t>(q)] == best); // exact: same expression, same argmin value
        }
    }
}

TEST_CASE("Donnelly's distance map is the exact distance to the column model", "[meso][edt]") {
    // Periodic, so the nearest column may be across the seam; heights continuous.
    const MesoHeightField hf = mesoField(9, 7, 6, [](int i, int j) { return std::fmod(0.7 * i * i + 1.3 * j, 6.0); });
    const DistanceMap m = buildDistanceMap(hf, 1);
    for (int k = 0; k < hf.layers; ++k)
        for (int y = 0; y < hf.height; ++y)
            for (int x = 0; x < hf.width; ++x) {
                // Outside: distance to the solid's half-lines; inside: minus that to the air's.
                double best = std::numeric_limits<double>::infinity(), air = best;
                for (int j = 0; j < hf.height; ++j)
                    for (int i = 0; i < hf.width; ++i)
                        for (int pj = -1; pj <= 1; ++pj)
                            for (int pi = -1; pi <= 1; ++pi) {
                                const double dx = x - (i + pi * hf.width), dy = y - (j + pj * hf.height);
                                const double up = std::max(0.0, k + 0.5 - static_cast<double>(hf.at(i, j)));
                                const double down = std::max(0.0, static_cast<double>(hf.at(i, j)) - (k + 0.5));
                                best = std::min(best, dy * dy + (dx * dx + up * up));
                                air = std::min(air, dy * dy + (dx * dx + down * down));
                            }
                INFO("sample " << x << "," << y << "," << k);
                CHECK(m.at(x, y, k) == static_cast<float>(best > 0 ? std::sqrt(best) : -std::sqrt(air)));
            }
}

TEST_CASE("directional distances never exceed the distance along any ray from their voxel", "[meso][ddm]") {
    // Steep walls, a one-texel spike and smooth slopes; 4 x 2 view cones, shadow cones and the
    // isotropic set. Rays from random points of each voxel in random directions of its cone,
    // traced exactly in double: the first hit is never closer than the stored distance.
    const MesoHeightField hf = dmtest::hardField(12, 12, 8);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (ConeSet cones : {ConeSet{4, 2, true, false}, ConeSet{8, 1, false, false}, ConeSet::all()}) {
        const DirectionalDistanceMap m = buildDdm(hf, cones);
        int zeros = 0, checked = 0;
        for (int c = 0; c < cones.count(); ++c)
            for (int k = 0; k < hf.layers; ++k)
                for (int j = 0; j < hf.height; ++j)
                    for (int i = 0; i < hf.width; ++i) {
                        const float stored = m.at(c, i, j, k);
                        zeros += stored == 0;
                        if (stored == 0) continue;
                        for (int s = 0; s < 6; ++s) {
                            const glm::dvec3 o(i + U(rng), j + U(rng), k + U(rng));
                            glm::dvec3 d;
                            do { // every other ray near the horizon, where the bands' bounds are tight
                                const double z = U(rng) * 2 - 1;
                                d = glm::normalize(glm::dvec3(U(rng) * 2 - 1, U(rng) * 2 - 1, s % 2 ? z * z * z * z * z : z));
                            } while (kern::dmConeIndex(d, cones.kernelM(), cones.n) != c || (!cones.shadow && !cones.isotropic && d.z > 0));
                            const MesoHit h = marchReference<double>(hf, o, d);
                            ++checked;
                            if (!h.hit) continue;
                            INFO(cones.name() << " cone " << c << " voxel " << i << "," << j << "," << k << " stored " << stored
                                              << " hit at " << h.t);
                            REQUIRE(h.t >= static_cast<double>(stored) - 1e-12);
                        }
                    }
        CHECK(zeros > 0);
        CHECK(checked > 1000);
    }
}

TEST_CASE("the DDM's search skips only boxes that cannot improve a cone", "[meso][ddm]") {
    // buildDdm searches the columns in a quadtree of blocks, starts each voxel from the boxes
    // that set its neighbour's bests and asks a box only of the cones it may still improve.
    // None of that may change a value: every voxel's map equals, bit for bit, the minimum over
    // every sub-box of every column in reach (the cap's ring and one more), each offered to
    // every cone in a plain loop.
    // Odd sizes and sizes below a block (the rings wrap onto the same columns), sub-cells 1 to
    // 3 and caps below, at and above the layers.
    struct Case {
        int w, h, layers, subcells;
        float cap;
        ConeSet cones;
    };
    const Case cases[] = {{12, 12, 8, 2, 0.0f, ConeSet{8, 2, false, false}}, {12, 12, 8, 2, 0.0f, ConeSet{4, 2, true, false}},
                          {12, 12, 8, 2, 0.0f, ConeSet{2, 1, false, false}}, {12, 12, 8, 2, 0.0f, ConeSet::all()},
                          {7, 5, 6, 3, 9.5f, ConeSet{8, 2, false, false}},   {3, 2, 5, 1, 4.5f, ConeSet{4, 2, true, false}},
                          {9, 6, 4, 2, 13.0f, ConeSet{4, 1, false, false}}};
    for (const Case& cs : cases) {
        const MesoHeightField hf = dmtest::hardField(cs.w, cs.h, cs.layers);
        const int S = cs.subcells;
        const ConeSet& cones = cs.cones;
        const DirectionalDistanceMap m = buildDdm(hf, cones, S, cs.cap);
        std::vector<detail::ConeTest> tests;
        for (int c = 0; c < cones.count(); ++c) tests.push_back(detail::coneTest(cones, c));
        detail::ConeSearch search(tests);
        const double bottom = -4.0 * hf.layers - 1.0;
        const int reach = static_cast<int>(std::ceil(m.cap)) + 1;
        int differ = 0, searched = 0;
        for (int k = 0; k < hf.layers; ++k)
            for (int j = 0; j < hf.height; ++j)
                for (int i = 0; i < hf.width; ++i) {
                    const glm::dvec4 h(hf.cell(i, j));
                    if (k + 1 <= std::min(std::min(h.x, h.y), std::min(h.z, h.w))) continue; // inside the solid: 0
                    ++searched;
                    search.reset(m.cap);
                    for (int cj = j - reach; cj <= j + reach; ++cj)
                        for (int ci = i - reach; ci <= i + reach; ++ci) {
                            const glm::dvec4 hc(hf.cell(ci, cj));
                            for (int b = 0; b < S; ++b)
                                for (int a = 0; a < S; ++a) {
                                    const double x0 = double(a) / S, x1 = double(a + 1) / S, y0 = double(b) / S, y1 = double(b + 1) / S;
                                    const auto H = [&](double x, double y) { return kern::dmBilerp(hc, glm::dvec2(x, y)); };
                                    const double top = std::max(std::max(H(x0, y0), H(x1, y0)), std::max(H(x1, y1), H(x0, y1)));
                                    const double bx = ci + x0, by = cj + y0;
                                    search.offer({{bx - (i + 1.0), by - (j + 1.0), bottom - (k + 1.0)}, {bx + 1.0 / S - i, by + 1.0 / S - j, top - k}},
                                                 search.allCones());
                                }
                        }
                    for (int c = 0; c < cones.count(); ++c)
                        differ += m.at(c, i, j, k) != detail::floatBelow(search.best[static_cast<std::size_t>(c)]);
                }
        INFO(cones.name() << ", " << cs.w << " x " << cs.h << " x " << cs.layers << ", sub-cells " << S << ", cap " << cs.cap << ": "
                           << searched << " voxels searched");
        CHECK(searched > cs.w * cs.h * cs.layers / 4);
        CHECK(differ == 0);
    }
}

TEST_CASE("directional distances bound the part of each box a cone reaches", "[meso][ddm]") {
    // A flat floor at height 2: from a voxel g = k - 2 above it, rays of the steep band (45 to
    // 90 degrees down) meet the floor after g at least, rays of the shallow band (0 to 45
    // degrees) after sqrt(2) g (at 45 degrees from the voxel's bottom). The bound to the whole
    // box below would be g for both; the cone's part of it is sqrt(2) g, less the cone slack
    // (1e-6 rad: a relative 1e-6) and float rounding. The isotropic set keeps g.
    const int n = 16, layers = 8;
    const MesoHeightField hf = mesoHeightField(n, n, layers, std::vector<float>(static_cast<std::size_t>(n * n), 2.0f));
    const ConeSet cones{4, 2, false, false};
    const DirectionalDistanceMap m = buildDdm(hf, cones);
    const DirectionalDistanceMap iso = buildDdm(hf, ConeSet::all());
    for (int k = 3; k < layers; ++k) {
        const double g = k - 2.0;
        for (int c = 0; c < cones.count(); ++c) {
            const bool shallow = c / cones.m == 0; // band 0: the first quarter turn below the horizon
            const double want = shallow ? std::sqrt(2.0) * g : g;
            INFO("layer " << k << " cone " << c);
            const double stored = static_cast<double>(m.at(c, 5, 7, k));
            CHECK(stored <= want);
            CHECK(stored >= want * (1 - 4e-6));
        }
        CHECK(iso.at(0, 5, 7, k) == static_cast<float>(g));
    }
}

TEST_CASE("cones: the kernel's index agrees with the builder's angular ranges", "[meso][ddm]") {
    std::mt19937 rng(3);
    std::normal_distribution<double> N(0.0, 1.0);
    for (ConeSet cones : {ConeSet{1, 1, true, false}, ConeSet{2, 1, true, false}, ConeSet{4, 2, true, false}, ConeSet{8, 2, true, false}}) {
        for (int s = 0; s < 4000; ++s) {
            const glm::dvec3 d = glm::normalize(glm::dvec3(N(rng), N(rng), N(rng)));
            const int c = kern::dmConeIndex(d, cones.m, cones.n);
            REQUIRE(c >= 0);
            REQUIRE(c < cones.count());
            double az[2], el[2];
            cones.range(c, az, el);
            double theta = std::atan2(d.y, d.x);
            if (theta < 0) theta += 2 * 3.14159265358979323846;
            const double phi = std::asin(d.z);
            CHECK(theta >= az[0] - 1e-12);
            CHECK(theta <= az[1] + 1e-12);
            CHECK(phi >= el[0] - 1e-12);
            CHECK(phi <= el[1] + 1e-12);
        }
    }
}

TEST_CASE("min-filtered levels hold the minimum and stay conservative", "[meso][ddm]") {
    const MesoHeightField hf = dmtest::hardField(16, 16, 8);
    const ConeSet cones{4, 1, false, false};
    const DirectionalDistanceMap fine = buildDdm(hf, cones);
    const DirectionalDistanceMap coarse = minFilter(fine);
    REQUIRE(coarse.width == 8);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (int c = 0; c < cones.count(); ++c)
        for (int k = 0; k < coarse.layers; ++k)
            for (int j = 0; j < coarse.height; ++j)
                for (int i = 0; i < coarse.width; ++i) {
                    float lo = std::numeric_limits<float>::infinity();
                    for (int e = 0; e < 8; ++e) lo = std::min(lo, fine.at(c, 2 * i + (e & 1), 2 * j + (e >> 1 & 1), 2 * k + (e >> 2)));
                    REQUIRE(coarse.at(c, i, j, k) == 0.5f * lo); // in coarse voxels
                    // A ray from anywhere in the coarse voxel (2x the size) within the cone.
                    const glm::dvec3 o(2 * (i + U(rng)), 2 * (j + U(rng)), 2 * (k + U(rng)));
                    glm::dvec3 d;
                    do {
                        d = glm::normalize(glm::dvec3(U(rng) * 2 - 1, U(rng) * 2 - 1, -U(rng)));
                    } while (kern::dmConeIndex(d, cones.m, cones.n) != c);
                    const MesoHit h = marchReference<double>(hf, o, d);
                    if (h.hit) REQUIRE(h.t >= static_cast<double>(lo) - 1e-12);
                }
    CHECK(coarse.cap == 0.5f * fine.cap);
    CHECK_THROWS_AS(minFilter(minFilter(minFilter(coarse))), ArgumentError); // 8 -> 4 -> 2: below 4
}

TEST_CASE("compression: atlas blocks read back bit for bit, the rest their block minimum or a plane below", "[meso][ddm]") {
    const MesoHeightField hf = dmtest::hardField(16, 16, 8);
    const ConeSet cones{4, 1, true, false};
    const DirectionalDistanceMap m = buildDdm(hf, cones);
    const float paper = std::numeric_limits<float>::infinity();
    const CompressedDdm c = compressDdm(m, 4, paper);
    CHECK(c.atlasBlocks() > 0);
    CHECK(c.ratio() > 1.0);
    CHECK(c.planeBlocks() == 0); // the paper's rule: free blocks keep their minimum
    // Each block: zeros only or free space spreading by at most the spread keep one value (the
    // minimum); other blocks the plane below them when no voxel reads more than half the spread
    // under its value and the zeros alone read 0; the rest whole.
    std::size_t previous = 0, planes = 0;
    for (const float spread : {paper, 2.0f, 1.0f, 0.0f}) {
        INFO("spread " << spread);
        const CompressedDdm cs = compressDdm(m, 4, spread);
        CHECK(cs.wordsValid());
        int exactReads = 0, minimumReads = 0, planeReads = 0;
        for (int cone = 0; cone < cones.count(); ++cone)
            for (int k = 0; k < m.layers; ++k)
                for (int j = 0; j < m.height; ++j)
                    for (int i = 0; i < m.width; ++i) {
                        const int bx = i / 4, by = j / 4, bz = k / 4;
                        float lo = std::numeric_limits<float>::infinity(), hi = 0;
                        for (int e = 0; e < 64; ++e) {
                            const float x = m.at(cone, bx * 4 + e % 4, by * 4 + e / 4 % 4, bz * 4 + e / 16);
                            lo = std::min(lo, x);
                            hi = std::max(hi, x);
                        }
                        int index = -1, kind = -1;
                        (void)kern::dmGridWordDistance(cs.grid[cs.gridIndex(cone, bx, by, bz)], index, kind);
                        const float got = cs.lookup(cone, i, j, k), value = m.at(cone, i, j, k);
                        const bool one = hi == 0 || (lo > 0 && hi - lo <= spread);
                        if (one) {
                            REQUIRE(kind == 0);
                            REQUIRE(std::memcmp(&got, &lo, sizeof got) == 0);
                            minimumReads += got != value;
                        } else if (kind == 2) {
                            // Conservative, within half the spread, 0 exactly where a surface
                            // may pass, and more than 0 elsewhere.
                            REQUIRE(got <= value);
                            REQUIRE(got >= value - 0.5f * spread);
                            REQUIRE((value == 0) == (got == 0));
                            ++planeReads;
                        } else {
                            REQUIRE(kind == 1);
                            REQUIRE(std::memcmp(&got, &value, sizeof got) == 0);
                            ++exactReads;
                        }
                    }
        CHECK(cs.atlasBlocks() >= previous); // a smaller spread stores more blocks whole
        previous = cs.atlasBlocks();
        planes += cs.planeBlocks();
        CHECK(exactReads > 0);
        if (spread == 0) CHECK((minimumReads == 0 && planeReads == 0)); // every block with two values is whole
        if (std::isinf(spread)) CHECK((minimumReads > 0 && planeReads == 0)); // the paper's rule keeps some minima
    }
    CHECK(planes > 0); // the finite spreads bound some free blocks by planes
    // The march finds the same hits through the compressed and the dense map.
    const ColumnQuadrics q = buildColumnQuadrics(hf);
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (int s = 0; s < 2000; ++s) {
        const glm::dvec3 o(U(rng) * 16, U(rng) * 16, 8.0);
        const glm::dvec3 d = glm::normalize(glm::dvec3(U(rng) * 2 - 1, U(rng) * 2 - 1, -0.05 - U(rng)));
        const MesoHit a = marchDdm<double>(DenseDdmView{&m}, cones, 8, &q, o, d, {});
        const MesoHit b = marchDdm<double>(CompressedDdmView{&c}, cones, 8, &q, o, d, {});
        REQUIRE(a.hit == b.hit);
        REQUIRE(a.t == Approx(b.t).margin(1e-9));
    }
    CHECK_THROWS_AS(compressDdm(m, 3), ArgumentError);
    CHECK_THROWS_AS(compressDdm(m, 4, -1.0f), ArgumentError);
    CHECK_THROWS_AS(compressDdm(m, 4, std::numeric_limits<float>::quiet_NaN()), ArgumentError);
}

TEST_CASE("quadrics of bilinear and triangular patches contain their patches", "[meso][quadric]") {
    std::mt19937 rng(13);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    for (int trial = 0; trial < 400; ++trial) {
        // General patches, and patches flattened towards planar ones (the degenerate branch).
        const double flat = trial % 4 == 0 ? 0.0 : std::pow(10.0, -(trial % 13));
        const glm::dvec3 P1(0, 0, 0), P2(1 + 0.3 * U(rng), 0.2 * U(rng), 0.2 * U(rng)), P4(0.2 * U(rng), 1 + 0.3 * U(rng), 0.2 * U(rng));
        const glm::dvec3 n = glm::normalize(glm::cross(P2 - P1, P4 - P1));
        const glm::dvec3 P3 = P2 + P4 - P1 + glm::dvec3(0.3 * U(rng), 0.3 * U(rng), 0) + flat * U(rng) * n;
        const glm::dvec3 c = 0.25 * (P1 + P2 + P3 + P4); // P(1/2, 1/2)
        const Quadric q = bilinearPatchQuadric(P1, P2, P3, P4, c - 0.1 * n);
        for (int s = 0; s < 16; ++s) {
            const double u = (s % 4) / 3.0, v = (s / 4) / 3.0;
            const glm::dvec3 p = (1 - u) * (1 - v) * P1 + u * (1 - v) * P2 + u * v * P3 + (1 - u) * v * P4;
            INFO("trial " << trial << " flat " << flat);
            CHECK(std::abs(q(p)) < 1e-9);
        }
        // Orientation: positive on the inside. (A strongly twisted, nearly planar patch's quadric
        // folds back close to the patch: its extension beyond [0, 1]^2 is near, so the probe
        // is short and skipped where the fold is nearer than it.)
        if (flat == 0 || flat >= 1e-2) {
            CHECK(q(c - 1e-3 * n) > 0);
            CHECK(q(c + 1e-3 * n) < 0);
        }
        const Quadric t = triangleQuadric(P1, P2, P4, c - n);
        CHECK(std::abs(t(0.2 * P1 + 0.3 * P2 + 0.5 * P4)) < 1e-12);
    }
    CHECK_THROWS_AS(bilinearPatchQuadric({0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {0, 0, -1}), ArgumentError);
    CHECK_THROWS_AS(triangleQuadric({0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {0, 0, -1}), ArgumentError);
}

TEST_CASE("ray-quadric roots of column quadrics equal the exact height-cell roots", "[meso][quadric]") {
    // The column quadric (Appendix B) and the direct cell equation (the reference) are two
    // formulations of one surface: in double their first hits agree to rounding.
    const MesoHeightField hf = dmtest::hardField(12, 12, 8);
    const ColumnQuadrics q = buildColumnQuadrics(hf);
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    int hits = 0;
    for (int s = 0; s < 20000; ++s) {
        const int i = static_cast<int>(rng() % 12), j = static_cast<int>(rng() % 12);
        const glm::dvec3 o(U(rng), U(rng), 8.0 * U(rng));
        const glm::dvec3 d = glm::normalize(glm::dvec3(U(rng) * 2 - 1, U(rng) * 2 - 1, U(rng) * 2 - 1));
        const glm::dvec4 h(hf.cell(i, j));
        // Exact polynomial evaluation needs the stored (float) quadric in double.
        const std::size_t at = 3 * static_cast<std::size_t>(j * 12 + i);
        const glm::dvec4 qa(q.q[at]), qb(q.q[at + 1]), qc(q.q[at + 2]);
        double sCell = 0, sQuad = 0;
        const double len = 0.5;
        const bool a = kern::dmRayHeightCell(o, d, h, len, 1e-14, sCell);
        const bool b = kern::dmRayQuadric(qa, qb, qc, o, d, len, 1e-14, sQuad);
        if (a != b) {
            // Only a tangent graze or a hit at the segment's end may differ.
            const double margin = 1e-5;
            const double fEnd = (o + len * d).z - kern::dmBilerp(h, glm::dvec2(o.x + len * d.x, o.y + len * d.y));
            INFO("cell " << i << "," << j << " o " << o.x << "," << o.y << "," << o.z << " fEnd " << fEnd);
            CHECK(std::abs(fEnd) < margin);
            continue;
        }
        if (a) {
            ++hits;
            INFO("cell " << i << "," << j);
            CHECK(sCell == Approx(sQuad).margin(1e-5));
        }
    }
    CHECK(hits > 2000);
}

TEST_CASE("quadratic roots: stable against long double on adversarial coefficients", "[meso][roots]") {
    // Cancellation (b^2 >> 4ac), a -> 0, near-double roots, scaled over decades; float and
    // double. Reference roots in long double from the same rounded coefficients.
    auto check = [](auto a, auto b, auto c, double relBound) {
        using real = decltype(a);
        real t0, t1;
        const int n = kern::dmQuadraticRoots(a, b, c, mesoRootTolerance<real>(), t0, t1);
        const long double A = a, B = b, C = c, disc = B * B - 4 * A * C;
        if (A == 0) {
            REQUIRE(n == (B != 0 ? 1 : 0));
            if (n) CHECK(std::abs(static_cast<long double>(t0) - (-C / B)) <= relBound * std::abs(C / B));
            return;
        }
        const long double scale = std::sqrt(B * B + std::abs(4 * A * C));
        if (disc < -1e-6L * scale * scale) {
            CHECK(n == 0);
            return;
        }
        if (disc < 0) return; // inside the tangent band: either answer is right
        REQUIRE(n == 2);
        const long double sq = std::sqrt(disc), q = -0.5L * (B + (B < 0 ? -sq : sq));
        long double r0 = q / A, r1 = C / q;
        if (r0 > r1) std::swap(r0, r1);
        // Each root to a few ULP of itself, except a near-double root, which is conditioned by
        // sqrt(eps) (the discriminant's own rounding): bound relative to the root spacing.
        const long double spread = std::sqrt(std::numeric_limits<real>::epsilon() * scale * scale) / std::abs(A);
        CHECK(std::abs(t0 - r0) <= relBound * std::abs(r0) + (disc < 1e-4L * scale * scale ? spread : 0));
        CHECK(std::abs(t1 - r1) <= relBound * std::abs(r1) + (disc < 1e-4L * scale * scale ? spread : 0));
    };
    std::mt19937_64 rng(21);
    std::uniform_real_distribution<double> U(-1.0, 1.0), E(-6.0, 6.0);
    for (int s = 0; s < 20000; ++s) {
        const double a = U(rng) * std::pow(10.0, E(rng)), b = U(rng) * std::pow(10.0, E(rng)), c = U(rng) * std::pow(10.0, E(rng));
        check(a, b, c, 8 * std::numeric_limits<double>::epsilon());
        check(static_cast<float>(a), static_cast<float>(b), static_cast<float>(c), 8 * std::numeric_limits<float>::epsilon());
        // Catastrophic cancellation: roots ~ -b/a and ~ -c/b, 12 decades apart.
        check(1e-6 * std::abs(a) + 1e-300, 1e6, c, 8 * std::numeric_limits<double>::epsilon());
        check(1e-3f, 1e3f, static_cast<float>(c), 8 * std::numeric_limits<float>::epsilon());
        // Near-double root: (t - r)^2 + tiny.
        const double r = U(rng) * 10;
        check(1.0, -2 * r, r * r + 1e-12 * U(rng), 8 * std::numeric_limits<double>::epsilon());
        check(1.0f, static_cast<float>(-2 * r), static_cast<float>(r * r), 8 * std::numeric_limits<float>::epsilon());
    }
    // The textbook formula (-b + sqrt(disc)) / 2a loses the small root where the stable one keeps it.
    const double a = 1, b = 1e8, c = 1;
    double t0, t1;
    REQUIRE(kern::dmQuadraticRoots(a, b, c, 1e-15, t0, t1) == 2);
    const double naive = (-b + std::sqrt(b * b - 4 * a * c)) / (2 * a);
    CHECK(t1 == Approx(-1e-8).epsilon(1e-15));
    CHECK(std::abs(naive - (-1e-8)) > 1e-10); // naive: off by > 1 %
    // a == 0 exactly, and a 1e-30: the finite root stays -c/b.
    REQUIRE(kern::dmQuadraticRoots(0.0, 2.0, -1.0, 1e-15, t0, t1) == 1);
    CHECK(t0 == 0.5);
    REQUIRE(kern::dmQuadraticRoots(1e-30, 2.0, -1.0, 1e-15, t0, t1) == 2);
    CHECK((t0 == 0.5 || t1 == 0.5));
    CHECK(kern::dmQuadraticRoots(0.0, 0.0, 1.0, 1e-15, t0, t1) == 0);
}

TEST_CASE("bad inputs are clear errors", "[meso][errors]") {
    CHECK_THROWS_WITH(mesoHeightField(0, 4, 4, {}), Catch::Contains("out of range"));
    CHECK_THROWS_WITH(mesoHeightField(4, 4, 4, std::vector<float>(15, 1.0f)), Catch::Contains("15 heights for 4 x 4"));
    std::vector<float> nan(16, 1.0f);
    nan[5] = std::numeric_limits<float>::quiet_NaN();
    CHECK_THROWS_WITH(mesoHeightField(4, 4, 4, nan), Catch::Contains("texel (1, 1)"));
    CHECK_THROWS_WITH(mesoHeightField(4, 4, 4, std::vector<float>(16, 5.0f)), Catch::Contains("not in [0, 4]"));
    CHECK_THROWS_WITH(mesoHeightField(4, 4, 1, std::vector<float>(16, 0.5f)), Catch::Contains("layers"));
    const MesoHeightField hf = mesoField(4, 4, 4, [](int, int) { return 1.0; });
    CHECK_THROWS_WITH(buildDdm(hf, ConeSet{0, 1, false, false}), Catch::Contains("zero cones"));
    CHECK_THROWS_WITH(buildDdm(hf, ConeSet{3, 1, false, false}), Catch::Contains("not supported"));
    CHECK_THROWS_WITH(buildDdm(hf, ConeSet::all(), 2, 1e6f), Catch::Contains("cap"));
    CHECK_THROWS_WITH(buildDdm(hf, ConeSet::all(), 2, std::numeric_limits<float>::quiet_NaN()), Catch::Contains("cap"));
    CHECK_THROWS_WITH(buildDdm(hf, ConeSet::all(), 2, -1.0f), Catch::Contains("cap"));
    struct Img {
        int width = 0, height = 0;
        std::vector<float> values;
    } empty;
    CHECK_THROWS_WITH(mesoHeightFieldFromImage(empty, 8), Catch::Contains("empty"));
    const DirectionalDistanceMap m = buildDdm(hf, ConeSet{4, 1, false, false});
    CHECK_THROWS_WITH(marchDdm<float>(DenseDdmView{&m}, m.cones, 4, nullptr, {1, 1, 4}, {0, 0, 1}, DdmMarch{256, false, 1}),
                      Catch::Contains("shadow cones"));
    CHECK_THROWS_WITH(marchDdm<float>(DenseDdmView{&m}, m.cones, 4, nullptr, {1, 1, 4}, {0, 0, -1}, DdmMarch{}),
                      Catch::Contains("quadric"));
    CHECK_THROWS_WITH(marchReference<double>(hf, {1, 1, 4}, {0, 0, -2}), Catch::Contains("unit direction"));
    CHECK_THROWS_WITH(marchHeightSearch<double>(hf, {1, 1, 4}, {0, 0, 1}, 8, 4), Catch::Contains("d.z < 0"));
}

namespace {
// Rays from the top plane in every direction of the lower hemisphere down to grazing ones
// (d.z = -0.01), from random points, seeded.
std::vector<std::pair<glm::dvec3, glm::dvec3>> viewRays(const MesoHeightField& hf, int count, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<std::pair<glm::dvec3, glm::dvec3>> rays;
    for (int s = 0; s < count; ++s) {
        const double a = 6.283185307179586 * U(rng), grazing = s % 4 == 0 ? 0.01 + 0.05 * U(rng) : 0.05 + U(rng);
        const glm::dvec3 d = glm::normalize(glm::dvec3(std::cos(a), std::sin(a), -grazing));
        rays.push_back({glm::dvec3(U(rng) * hf.width, U(rng) * hf.height, hf.layers), d});
    }
    return rays;
}
} // namespace

TEST_CASE("conservative marchers find the exact first hit, thin walls and grazing rays included", "[meso][march]") {
    // DDM + quadric: the hit is the analytic root in the first voxel the surface crosses, so it
    // equals the exact reference (double: 1e-9 voxels; float: 2e-3 voxels = a few float ULP of
    // the ray parameter on a 12-layer slab crossed at grazing angles). Without quadrics it
    // stops at the first voxel whose distance is 0: never beyond the reference hit.
    const MesoHeightField hf = dmtest::hardField(24, 24, 12);
    const ColumnQuadrics q = buildColumnQuadrics(hf);
    const auto rays = viewRays(hf, 1500, 23);
    for (ConeSet cones : {ConeSet::all(), ConeSet{2, 1, false, false}, ConeSet{4, 1, false, false}, ConeSet{8, 2, false, false}}) {
        const DirectionalDistanceMap m = buildDdm(hf, cones);
        const CompressedDdm c = compressDdm(m, 4);
        for (int exitRule : {0, 1}) {
            DdmMarch opt;
            opt.exitRule = exitRule;
            opt.maxIterations = 4096;
            DdmMarch bare = opt;
            bare.quadrics = false;
            for (const auto& [o, d] : rays) {
                const MesoHit ref = marchReference<double>(hf, o, d);
                const MesoHit hd = marchDdm<double>(CompressedDdmView{&c}, cones, hf.layers, &q, o, d, opt);
                const MesoHit hf32 = marchDdm<float>(CompressedDdmView{&c}, cones, hf.layers, &q, o, d, opt);
                const MesoHit stop = marchDdm<double>(CompressedDdmView{&c}, cones, hf.layers, nullptr, o, d, bare);
                INFO(cones.name() << " exit rule " << exitRule << " o " << o.x << "," << o.y << " d " << d.x << "," << d.y << "," << d.z
                                  << " ref " << ref.hit << " " << ref.t);
                REQUIRE(ref.hit);
                REQUIRE(hd.hit);
                REQUIRE(hd.t == Approx(ref.t).margin(1e-9));
                REQUIRE(hf32.hit);
                REQUIRE(std::abs(hf32.t - ref.t) < 2e-3 * std::max(1.0, ref.t / hf.layers));
                REQUIRE(stop.hit);
                REQUIRE(stop.t <= ref.t + 1e-9);
            }
        }
    }
}

TEST_CASE("rays that start inside, shadow rays that leave or are blocked", "[meso][march]") {
    const MesoHeightField hf = dmtest::hardField(16, 16, 8);
    const ColumnQuadrics q = buildColumnQuadrics(hf);
    const ConeSet cones{4, 1, true, false};
    const DirectionalDistanceMap m = buildDdm(hf, cones);
    const DenseDdmView view{&m};
    // Inside the solid under the slope: a hit at t = 0, whatever the direction.
    for (const glm::dvec3 d : {glm::dvec3(0, 0, -1), glm::normalize(glm::dvec3(1, 1, 0.3)), glm::dvec3(1, 0, 0)}) {
        const glm::dvec3 o(7.3, 5.2, 0.5);
        CHECK(marchReference<double>(hf, o, d).t == 0);
        const MesoHit h = marchDdm<double>(view, cones, hf.layers, &q, o, d, {});
        CHECK(h.hit);
        CHECK(h.t == 0);
    }
    // Straight up from above the surface: lit; from the floor (j = 0..1) towards the thin wall
    // at i = 2 (height 7.75) at 20 degrees: blocked, at the same t as the reference.
    const glm::dvec3 up(0, 0, 1);
    CHECK_FALSE(marchDdm<double>(view, cones, hf.layers, &q, {5.5, 5.5, 4.0}, up, {}).hit);
    CHECK_FALSE(marchReference<double>(hf, {5.5, 5.5, 4.0}, up).hit);
    const glm::dvec3 toWall = glm::normalize(glm::dvec3(-1, 0, std::tan(0.35)));
    const glm::dvec3 floor(6.0, 0.5, 0.01);
    const MesoHit ref = marchReference<double>(hf, floor, toWall);
    const MesoHit h = marchDdm<double>(view, cones, hf.layers, &q, floor, toWall, {});
    REQUIRE(ref.hit);
    CHECK(h.hit);
    CHECK(h.t == Approx(ref.t).margin(1e-9));
    // A ray that leaves through the top: a miss for the reference and the marchers.
    const glm::dvec3 out = glm::normalize(glm::dvec3(1, 0.2, 0.5));
    CHECK_FALSE(marchReference<double>(hf, {9.5, 9.5, 7.5}, out).hit);
    CHECK_FALSE(marchDdm<double>(view, cones, hf.layers, &q, {9.5, 9.5, 7.5}, out, {}).hit);
}

TEST_CASE("relief mapping, POM and Donnelly's map converge as their step counts grow", "[meso][march]") {
    // On a smooth field (no thin features) the baselines' mean hit error falls with their
    // knob; with few steps relief mapping misses thin walls, which the table reports.
    const MesoHeightField hf = mesoField(32, 32, 8, [](int i, int j) { return 3.0 + 2.0 * std::sin(0.3 * i) * std::cos(0.25 * j); });
    const DistanceMap dm = buildDistanceMap(hf);
    const auto rays = viewRays(hf, 600, 29);
    auto meanError = [&](auto march) {
        double sum = 0;
        int n = 0;
        for (const auto& [o, d] : rays) {
            if (d.z > -0.3) continue; // grazing rays need steps in proportion to their length
            ++n;
            const MesoHit ref = marchReference<double>(hf, o, d);
            const MesoHit h = march(o, d);
            sum += glm::length(h.point(o, d) - ref.point(o, d));
        }
        return sum / n;
    };
    const double relief8 = meanError([&](auto o, auto d) { return marchHeightSearch<float>(hf, o, d, 8, 2); });
    const double relief64 = meanError([&](auto o, auto d) { return marchHeightSearch<float>(hf, o, d, 64, 8); });
    const double pom8 = meanError([&](auto o, auto d) { return marchHeightSearch<float>(hf, o, d, 8, -1); });
    const double pom64 = meanError([&](auto o, auto d) { return marchHeightSearch<float>(hf, o, d, 64, -1); });
    const double dm8 = meanError([&](auto o, auto d) { return marchDistanceMap<float>(dm, o, d, 8, 0.02); });
    const double dm64 = meanError([&](auto o, auto d) { return marchDistanceMap<float>(dm, o, d, 64, 0.02); });
    CAPTURE(relief8, relief64, pom8, pom64, dm8, dm64);
    CHECK(relief64 < 0.5 * relief8);
    CHECK(pom64 < 0.5 * pom8);
    CHECK(dm64 < dm8);
    CHECK(relief64 < 0.05);
    CHECK(pom64 < 0.05);
}

TEST_CASE("the mesostructure file round trip is bit for bit; damage is a clear error", "[meso][file]") {
    const MesoMaps m = buildMesoMaps(dmtest::hardField(8, 8, 8), {ConeSet{2, 1, true, false}, 4, 2});
    const std::string path = std::string(DISPMAP_TEST_BINARY_DIR) + "/meso_roundtrip.dmm";
    saveMesoMaps(m, path);
    const MesoMaps r = loadMesoMaps(path);
    CHECK(r.field.h == m.field.h);
    CHECK(std::memcmp(r.distance.d.data(), m.distance.d.data(), m.distance.bytes()) == 0);
    CHECK(r.ddm.grid == m.ddm.grid);
    CHECK(std::memcmp(r.ddm.atlas.data(), m.ddm.atlas.data(), m.ddm.atlas.size() * 4) == 0);
    {
        // Plane blocks (free space bounded by a plane) round trip too: a wider field has them.
        const MesoMaps w = buildMesoMaps(dmtest::hardField(16, 16, 8), {ConeSet{2, 1, true, false}, 4, 2});
        REQUIRE(w.ddm.planeBlocks() > 0);
        saveMesoMaps(w, path + ".planes");
        const MesoMaps wr = loadMesoMaps(path + ".planes");
        CHECK(wr.ddm.grid == w.ddm.grid);
        CHECK(std::memcmp(wr.ddm.planes.data(), w.ddm.planes.data(), w.ddm.planes.size() * 4) == 0);
        CHECK(wr.ddm.planes.size() == w.ddm.planes.size());
    }
    CHECK(std::memcmp(r.quadrics.q.data(), m.quadrics.q.data(), m.quadrics.bytes()) == 0);
    CHECK(r.ddm.cones.name() == m.ddm.cones.name());
    {
        // A version-1 file (before plane blocks: no plane count) still loads: the maps of the
        // paper's rule (no planes) written as version 2, the count cut out, the version set to 1.
        MesoMapOptions paper{ConeSet{2, 1, true, false}, 4, std::numeric_limits<float>::infinity()};
        const MesoMaps p = buildMesoMaps(dmtest::hardField(8, 8, 8), paper);
        REQUIRE(p.ddm.planeBlocks() == 0);
        saveMesoMaps(p, path + ".v2");
        std::vector<unsigned char> v1 = detail::readFileBytes(path + ".v2", "test");
        const std::size_t countAt = 36 + 4 * 64 + 4 * 64 * 8 + 4 + 4 * p.ddm.grid.size() + 4 + 4 * p.ddm.atlas.size();
        REQUIRE((v1[countAt] == 0 && v1[countAt + 1] == 0 && v1[countAt + 2] == 0 && v1[countAt + 3] == 0));
        v1.erase(v1.begin() + static_cast<std::ptrdiff_t>(countAt), v1.begin() + static_cast<std::ptrdiff_t>(countAt + 4));
        v1[8] = 1;
        v1.resize(v1.size() - 4);
        const std::uint32_t crc = detail::crc32Of(v1.data(), v1.size());
        for (int b = 0; b < 4; ++b) v1.push_back(static_cast<unsigned char>(crc >> (8 * b)));
        detail::writeFileAtomically(path + ".v1", v1, "test");
        const MesoMaps old = loadMesoMaps(path + ".v1");
        CHECK(old.ddm.grid == p.ddm.grid);
        CHECK(old.ddm.planes.empty());
    }
    // Flip a byte in the middle; cut the file; not a file at all.
    std::vector<unsigned char> bytes = detail::readFileBytes(path, "test");
    std::vector<unsigned char> bad = bytes;
    bad[bad.size() / 2] ^= 0x40;
    detail::writeFileAtomically(path + ".bad", bad, "test");
    CHECK_THROWS_WITH(loadMesoMaps(path + ".bad"), Catch::Contains("checksum"));
    bad.assign(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(bytes.size() / 3));
    detail::writeFileAtomically(path + ".bad", bad, "test");
    CHECK_THROWS_AS(loadMesoMaps(path + ".bad"), FileError);
    CHECK_THROWS_WITH(loadMesoMaps(DISPMAP_TEST_DATA "/skimage_brick.png"), Catch::Contains("bad magic"));
    // Damage behind a valid checksum: the field checks themselves. Offsets: magic 8, version 4,
    // sizes 12, cones 4, block at 28, subsamples at 32, heights from 36.
    const auto withCrc = [&](std::vector<unsigned char> b) {
        const std::uint32_t crc = detail::crc32Of(b.data(), b.size() - 4);
        for (int i = 0; i < 4; ++i) b[b.size() - 4 + static_cast<std::size_t>(i)] = static_cast<unsigned char>(crc >> (8 * i));
        detail::writeFileAtomically(path + ".bad", b, "test");
    };
    bad = bytes;
    bad[28] = 3; // block 3 does not divide 8
    withCrc(bad);
    CHECK_THROWS_WITH(loadMesoMaps(path + ".bad"), Catch::Contains("block 3"));
    bad = bytes;
    bad[36 + 3] = 0x7f; // the first height becomes NaN / Inf
    bad[36 + 2] = 0xc0;
    withCrc(bad);
    CHECK_THROWS_WITH(loadMesoMaps(path + ".bad"), Catch::Contains("not finite"));
    bad = bytes;
    bad.insert(bad.end() - 4, {0, 0, 0, 0}); // trailing bytes before the checksum
    withCrc(bad);
    CHECK_THROWS_WITH(loadMesoMaps(path + ".bad"), Catch::Contains("unexpected bytes"));
    // A grid word naming an atlas block that does not exist: find the first atlas word.
    const std::size_t texels = 64, gridAt = 36 + 4 * texels + 4 * texels * 8 + 4;
    bool patched = false;
    for (std::size_t w = 0; w < m.ddm.grid.size() && !patched; ++w)
        if (m.ddm.grid[w] >> 31) {
            bad = bytes;
            bad[gridAt + 4 * w] = 0xff;
            bad[gridAt + 4 * w + 1] = 0xff;
            withCrc(bad);
            CHECK_THROWS_WITH(loadMesoMaps(path + ".bad"), Catch::Contains("missing atlas block"));
            patched = true;
        }
    CHECK(patched);
    MesoMapOptions partial;
    partial.ddm = false;
    CHECK_THROWS_WITH(saveMesoMaps(buildMesoMaps(dmtest::hardField(8, 8, 8), partial), path + ".partial"), Catch::Contains("not built"));
    CHECK_THROWS_WITH(loadMesoMaps(path + ".missing"), Catch::Contains("cannot open"));
}

TEST_CASE("non-height-field mesostructure: beads from a mesh", "[meso][solid]") {
    // Two beads floating above the floor (an overhang no height field has), one touching the
    // tile's edge x = 12. Conservative: rays from random points of a voxel in its cone never hit
    // closer than stored; the DDM march finds the exact first hit of the triangles.
    std::vector<glm::dvec3> v;
    std::vector<std::array<int, 3>> t;
    appendUvSphere({4, 4, 4}, 2.5, 8, v, t);
    appendUvSphere({11.0, 9, 5}, 2.0, 8, v, t);
    v.push_back({0, 0, 1.5}); // pins the bounding box: the tile is [0, 12]^2, the floor below z = 1.5
    v.push_back({12, 12, 1.5});
    t.push_back({static_cast<int>(v.size()) - 2, static_cast<int>(v.size()) - 2, static_cast<int>(v.size()) - 1}); // degenerate, ignored
    const MesoSolid s = mesoSolidFromMesh(v, t, 12, 12, 8, 2, 0.0);
    CHECK(s.solidShare() > 0.02);
    CHECK(s.solidShare() < 0.3);
    const ConeSet cones{4, 1, true, false};
    const DirectionalDistanceMap m = buildSolidDdm(s, cones);
    const CompressedDdm c = compressDdm(m, 4);
    std::mt19937 rng(31);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (int n = 0; n < 3000; ++n) {
        const int i = static_cast<int>(rng() % 12), j = static_cast<int>(rng() % 12), k = static_cast<int>(rng() % 8);
        const glm::dvec3 o(i + U(rng), j + U(rng), k + U(rng));
        const glm::dvec3 d = glm::normalize(glm::dvec3(U(rng) * 2 - 1, U(rng) * 2 - 1, U(rng) * 2 - 1));
        const int cone = kern::dmConeIndex(d, cones.m, cones.n);
        const MesoHit ref = marchSolidReference(s, o, d);
        if (ref.hit) REQUIRE(ref.t >= static_cast<double>(m.at(cone, i, j, k)) - 1e-9);
        const MesoHit h = marchDdmSolid(CompressedDdmView{&c}, cones, s, o, d);
        INFO("o " << o.x << "," << o.y << "," << o.z << " d " << d.x << "," << d.y << "," << d.z);
        REQUIRE(h.hit == ref.hit);
        if (h.hit) REQUIRE(h.t == Approx(ref.t).margin(1e-9));
    }
    // Donnelly's map of the solid: negative inside a bead, positive far above.
    const DistanceMap dm = buildSolidDistanceMap(s);
    CHECK(dm.at(4, 4, 4) < 0);
    CHECK(dm.at(8, 2, 7) > 1);
    CHECK_THROWS_WITH(mesoSolidFromMesh(v, {}, 12, 12, 8), Catch::Contains("no triangles"));
    CHECK_THROWS_WITH(mesoSolidFromMesh(v, {{0, 1, 99999}}, 12, 12, 8), Catch::Contains("out of range"));
    CHECK_THROWS_WITH(mesoSolidFromMesh(v, t, 12, 12, 2), Catch::Contains("more than 2 layers"));
    std::vector<glm::dvec3> flat = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    CHECK_THROWS_WITH(mesoSolidFromMesh(flat, {{0, 1, 2}}, 12, 12, 8), Catch::Contains("flat"));
    flat[1].x = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH(mesoSolidFromMesh(flat, {{0, 1, 2}}, 12, 12, 8), Catch::Contains("not finite"));
}

} // namespace dmtest_meso

namespace dmtest_meso {

namespace {
// Four beads in 16 x 16 x 16 voxels (backend_vulkan/parity's solid): one on the floor, one
// floating, two across the tile's sides x = 0 and y = 16.
MesoSolid fourBeads() {
    std::vector<glm::dvec3> v;
    std::vector<std::array<int, 3>> t;
    appendUvSphere({4, 4, 3}, 3.0, 8, v, t);     // on the floor
    appendUvSphere({11, 10, 9}, 2.5, 8, v, t);   // floating: an overhang
    appendUvSphere({0.5, 9, 5}, 2.0, 6, v, t);   // across the side x = 0: its copy in the tile before
    appendUvSphere({8, 15, 12}, 2.5, 8, v, t);   // across the side y = 16
    // The tile: [0, 16]^2 in the mesh's units, the floor at z = 0.
    return mesoSolidFromMesh(v, t, 16, 16, 16, MesoSolidTile{{0, 0, 0}, 16.0});
}
// Their maps: 4 x 1 view cones (and shadow cones, which rays bent back up need), no distance map.
MesoMaps fourBeadMaps(const MesoSolid& s, bool shadowCones = true) {
    MesoMapOptions opt;
    opt.cones = ConeSet{4, 1, shadowCones, false};
    opt.distance = false;
    return buildMesoSolidMaps(s, opt);
}
} // namespace

TEST_CASE("the solid's march in float (the GPU's) finds the double reference's triangles", "[meso][solid]") {
    const MesoSolid s = fourBeads();
    const MesoMaps maps = fourBeadMaps(s);
    REQUIRE(maps.isSolid());
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    int rays = 0, agree = 0, triangleHits = 0;
    double worst = 0;
    for (int n = 0; n < 4000; ++n) {
        // From the top over three periods (every fourth from inside the slab), down; shadow
        // rays up from anywhere in the slab.
        const bool up = n % 5 == 4;
        glm::dvec3 o(U(rng) * 48 - 16, U(rng) * 48 - 16, n % 4 == 0 || up ? U(rng) * 16 : 16.0);
        const double z = (n % 3 == 0 ? 0.01 + 0.04 * U(rng) : 0.05 + 0.95 * U(rng)) * (up ? 1 : -1), az = 6.283185307179586 * U(rng);
        const glm::dvec3 d = glm::normalize(glm::dvec3(std::sqrt(1 - z * z) * std::cos(az), std::sqrt(1 - z * z) * std::sin(az), z));
        const glm::dvec3 of{glm::vec3(o)}, df{glm::vec3(d)}; // the float ray, as the GPU has it
        const MesoHit ref = marchSolidReference(s, of, df);
        const MesoSolidHit h = marchDdmSolid<float>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, s, of, df, 1024, 1);
        ++rays;
        INFO("o " << of.x << "," << of.y << "," << of.z << " d " << df.x << "," << df.y << "," << df.z);
        if (h.hit != ref.hit) continue;
        // float: the vertices rounded to 2^-24 of 16 voxels, t (up to ~1600 voxels along a
        // grazing ray) carried in float through every step: 2^-24 t a rounding, ~100 of them;
        // 1e-5 max(t, 16) allows that and is far below a pixel.
        const double err = h.hit ? std::abs(h.t - ref.t) / std::max(ref.t, 16.0) : 0.0;
        worst = std::max(worst, err);
        agree += err <= 1e-5 ? 1 : 0;
        if (h.triangle >= 0) {
            ++triangleHits;
            // The hit lies on its triangle (a + u e1 + v e2), or on a copy of it a whole number
            // of tiles away: compare modulo the tile.
            const auto tri = static_cast<std::size_t>(h.triangle);
            const glm::dvec3 p = glm::dvec3(s.triangleRow(tri, 0)) + h.uv.x * glm::dvec3(s.triangleRow(tri, 1)) + h.uv.y * glm::dvec3(s.triangleRow(tri, 2));
            const glm::dvec3 q = of + h.t * df;
            const glm::dvec3 gap = q - p;
            CHECK(std::abs(gap.x - 16 * std::round(gap.x / 16)) < 1e-3);
            CHECK(std::abs(gap.y - 16 * std::round(gap.y / 16)) < 1e-3);
            CHECK(std::abs(gap.z) < 1e-3);
        }
    }
    INFO("agree " << agree << " of " << rays << ", worst |dt| / max(t, 16) " << worst << ", triangle hits " << triangleHits);
    // A float ray that grazes a triangle's edge may pass on the other side of it: a handful of
    // 4000 (0 measured with this seed; 0.5 % allowed).
    CHECK(agree >= rays - rays / 200);
    CHECK(triangleHits > rays / 4); // the beads are hit, not only the floor
    // The height-field marchers do not apply.
    MesoTechnique relief;
    relief.method = MesoMethod::Relief;
    CHECK_THROWS_WITH(marchMeso<float>(maps, relief, {1, 1, 16}, {0, 0, -1}), Catch::Contains("not a solid"));
    CHECK_THROWS_WITH(buildMesoSolidMaps(MesoSolid{}), Catch::Contains("empty"));
}

TEST_CASE("a bent ray's solid march finds the first crossing of its chords with the triangles", "[meso][solid][silhouette]") {
    // On a curved base the solid is marched along the bent ray kern::dmBentPoint (with curve 0
    // the parabola P(t) = o + t d - bend t^2 z) as chords (kern::dmMesoMarchDdmBent with `solid`).
    // The reference rebuilds the same chords (their count from the rule written out here: as few
    // as keep each within 0.05 voxels of the curve, z'' len^2 / 8, at most 64) and walks each voxel by voxel in double with every
    // copy of every triangle listed there (marchSolidReference up to the chord's end; the last
    // chord of a ray that reaches the floor goes on straight): its first crossing is the hit, a
    // chord that leaves through the top or a ray bent back up to the top is a miss.
    const MesoSolid s = fourBeads();
    const MesoMaps maps = fourBeadMaps(s);
    MesoTechnique tq;
    tq.iterations = 1024;
    const double L = s.layers, chordError = kMesoChordError;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    int hits = 0, beads = 0, misses = 0, bentUp = 0, agreeFloat = 0, rays = 0, manyChords = 0;
    for (int n = 0; n < 3000; ++n) {
        const double elev = n % 3 == 0 ? 0.02 + 0.15 * U(rng) : 0.1 + 1.3 * U(rng), az = 6.283185307179586 * U(rng);
        const glm::dvec3 d(std::cos(elev) * std::cos(az), std::cos(elev) * std::sin(az), -std::sin(elev));
        const glm::dvec3 o(48.0 * U(rng) - 16.0, 48.0 * U(rng) - 16.0, L);
        // Every third ray's depth follows a convex curvature (MesoBend::curve, kern::dmBentPoint).
        const double bend = n % 10 == 0 ? 0.0 : (n % 2 == 0 ? -1.0 : 1.0) * std::exp(-9.0 + 7.0 * U(rng)), curve = n % 3 == 1 ? -0.5 * U(rng) / L : 0.0;
        // Where the curve ends: the floor's root (the quadric's level L + curve L^2 / 2), or the
        // top again when bent back up first; the chords: as few as keep each within chordError of
        // it, z'' len^2 / 8 with z'' <= D' (2 |bend| + |curve| D'^2 F'^2).
        const double level = L + 0.5 * curve * L * L, disc = d.z * d.z + 4.0 * bend * level;
        double tEnd = bend == 0 ? -L / d.z : disc >= 0 ? 2.0 * level / (std::sqrt(disc) - d.z) : -1.0;
        const bool endsAtTop = bend < 0 && (tEnd < 0 || d.z / bend < tEnd);
        if (endsAtTop) tEnd = d.z / bend;
        const double rate = 1.0 / (1.0 + curve * L), slope = std::max(std::abs(d.z), std::abs(2.0 * bend * tEnd - d.z));
        const double zpp = rate * (2.0 * std::abs(bend) + std::abs(curve) * rate * rate * slope * slope);
        const int chords = bend == 0 ? 1 : std::max(static_cast<int>(std::min(std::ceil(tEnd * std::sqrt(zpp / (8.0 * chordError))), 64.0)), 1);
        manyChords += chords > 8 ? 1 : 0;
        bool refHit = false;
        double refT = tEnd;
        for (int k = 0; k < chords; ++k) {
            const double ta = tEnd * (double(k) / chords), tb = tEnd * (double(k + 1) / chords);
            const glm::dvec3 pa = kern::dmBentPoint(o, d, bend, curve, ta), pb = kern::dmBentPoint(o, d, bend, curve, tb);
            const double len = glm::length(pb - pa);
            const glm::dvec3 u = (pb - pa) / len;
            const bool open = k == chords - 1 && !endsAtTop;
            const MesoHit r = marchSolidReference(s, pa, bend == 0 ? d : u, 1 << 20, open || bend == 0 ? std::numeric_limits<double>::infinity() : len);
            if (r.hit && (open || r.t <= len)) {
                refHit = true;
                refT = bend == 0 ? r.t : ta + (tb - ta) * (r.t / len);
                break;
            }
            if (!r.hit && r.t <= len) break; // out through the top
        }
        glm::dvec3 slab;
        const MesoSolidHit h = marchDdmSolidBent<double>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, s, o, d, MesoBend(bend, curve), tq.iterations, 1, &slab);
        INFO("n " << n << " o " << o.x << "," << o.y << " d " << d.x << "," << d.y << "," << d.z << " bend " << bend << " curve " << curve << " chords " << chords
                  << ": march " << h.hit << " t " << h.t << " (" << h.iterations << " it), reference " << refHit << " t " << refT);
        ++rays;
        REQUIRE(h.hit == refHit);
        REQUIRE(h.iterations < tq.iterations); // no hit from running out
        bentUp += endsAtTop ? 1 : 0;
        if (!h.hit) {
            ++misses;
            CHECK(h.triangle == -1);
            continue;
        }
        ++hits;
        CHECK(h.t == Approx(refT).margin(1e-9)); // both in double, the same chords
        // The slab point is on the chord at t, within the chord error of the curve.
        CHECK(glm::length(slab - kern::dmBentPoint(o, d, bend, curve, h.t)) <= chordError + 1e-9);
        if (h.triangle >= 0) {
            ++beads;
            // On its triangle (a copy a whole number of tiles away).
            const auto tri = static_cast<std::size_t>(h.triangle);
            const glm::dvec3 gap = slab - glm::dvec3(s.triangleRow(tri, 0) + h.uv.x * s.triangleRow(tri, 1) + h.uv.y * s.triangleRow(tri, 2));
            CHECK(std::abs(gap.x - 16 * std::round(gap.x / 16)) < 1e-9);
            CHECK(std::abs(gap.y - 16 * std::round(gap.y / 16)) < 1e-9);
            CHECK(std::abs(gap.z) < 1e-9);
        }
        // In float (the GPU's arithmetic): the same answer to 1e-5 max(t, 16) (as the straight
        // solid march above: the chords' ends and directions rounded to float as well).
        const MesoHit f = marchMesoBent<float>(maps, tq, o, d, MesoBend(bend, curve));
        agreeFloat += f.hit && std::abs(f.t - h.t) <= 1e-5 * std::max(h.t, 16.0) ? 1 : 0;
    }
    INFO(rays << " rays: " << hits << " hits (" << beads << " on a bead), " << misses << " misses (" << bentUp << " bent back up), "
              << agreeFloat << " float hits as the double's, " << manyChords << " with more than 8 chords");
    CHECK(beads > hits / 4);
    CHECK(misses > 50);
    CHECK(bentUp > 50);
    CHECK(manyChords > 100);
    // A float ray grazing a triangle's edge may pass on its other side (0.5 % allowed).
    CHECK(agreeFloat >= hits - hits / 200);
    // A bend of 0 is the straight march, bit for bit; the errors.
    const glm::dvec3 o(3.3, 7.1, L), d = glm::normalize(glm::dvec3(0.7, 0.2, -0.3));
    const MesoSolidHit a = marchDdmSolidBent<float>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, s, o, d, 0.0),
                       b = marchDdmSolid<float>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, s, o, d);
    CHECK((a.hit == b.hit && a.t == b.t && a.iterations == b.iterations && a.triangle == b.triangle && a.uv == b.uv));
    CHECK_THROWS_WITH(marchDdmSolidBent<float>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, s, o - glm::dvec3(0, 0, 1), d, 0.01),
                      Catch::Contains("must enter at the top"));
    CHECK_THROWS_WITH(marchDdmSolidBent<float>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, s, o, d, std::nan("")), Catch::Contains("finite bend"));
    const MesoMaps viewOnly = fourBeadMaps(s, false);
    CHECK_THROWS_WITH(marchMesoBent<float>(viewOnly, tq, o, d, -0.01), Catch::Contains("needs shadow cones"));
    MesoTechnique relief;
    relief.method = MesoMethod::Relief;
    CHECK_THROWS_WITH(marchMesoBent<float>(maps, relief, o, d, 0.01), Catch::Contains("not a solid"));
}

TEST_CASE("the solid's corner normals survive the GPU's packing; voxel normals reach the world", "[meso][solid]") {
    const MesoSolid s = fourBeads();
    const PackedSolid packed = packSolid(s);
    const std::vector<glm::uvec4>& rows = packed.triangles;
    REQUIRE(rows.size() == 3 * s.triangles.size());
    // The lists: each voxel's range indexes the lists themselves; each entry's word names its
    // triangle and the tile of the voxel it was listed from.
    REQUIRE(packed.lists.size() == s.entryStart.size() + s.entries.size());
    CHECK(packed.lists.front() == s.entryStart.size());
    CHECK(packed.lists[s.entryStart.size() - 1] == packed.lists.size());
    for (std::size_t e = 0; e < s.entries.size(); ++e) {
        const std::uint32_t w = packed.lists[s.entryStart.size() + e];
        const MesoSolidEntry& en = s.entries[e];
        CHECK(static_cast<int>(w & 0xffffffu) == en.triangle);
        CHECK(static_cast<int>((w >> 24) & 15u) - 8 == kern::dmFloorDiv(en.voxel.x, s.width));
        CHECK(static_cast<int>(w >> 28) - 8 == kern::dmFloorDiv(en.voxel.y, s.height));
    }
    CHECK(s.bytes() == 4 * packed.lists.size() + 16 * rows.size());
    // The bead across x = 0 is listed from the tile before (a negative tile), the one across
    // y = 16 from the tile after.
    CHECK(std::any_of(s.entries.begin(), s.entries.end(), [](const MesoSolidEntry& e) { return e.voxel.x < 0; }));
    CHECK(std::any_of(s.entries.begin(), s.entries.end(), [&](const MesoSolidEntry& e) { return e.voxel.y >= s.height; }));
    double worst = 0;
    for (std::size_t e = 0; e < s.triangles.size(); ++e)
        for (int part = 0; part < 3; ++part) {
            const glm::uvec4& r = rows[3 * e + static_cast<std::size_t>(part)];
            const glm::vec3 row(s.triangleRow(e, part));
            CHECK(glm::uintBitsToFloat(r.x) == row.x);
            CHECK(glm::uintBitsToFloat(r.z) == row.z);
            const glm::dvec3 n = kern::dmOctDecode(kern::dmUnpackSnorm2x16(r.w, 32767.0));
            // GLSL's rule (the spec's division; GLM multiplies by 1 / 32767, an ULP off at times).
            const auto lo = static_cast<std::int16_t>(r.w & 0xffffu), hi = static_cast<std::int16_t>(r.w >> 16);
            CHECK(kern::dmUnpackSnorm2x16(r.w, 32767.0f) ==
                  glm::vec2(static_cast<float>(std::max(-1.0, lo / 32767.0)), static_cast<float>(std::max(-1.0, hi / 32767.0))));
            worst = std::max(worst, glm::length(n - s.normals[static_cast<std::size_t>(s.triangles[e][static_cast<std::size_t>(part)])]));
        }
    // snorm16 of the octahedral coordinates: steps of 2^-15, at most ~3 of them in the sphere's
    // direction after the fold (Cigolle et al. Table 1: 16-bit oct, max error 0.005 degrees).
    CHECK(worst < 2e-4);
    // A bead's corner normals point away from its centre (outward triangles).
    int outward = 0, total = 0;
    const glm::dvec3 centre = (s.vertices[0] + s.vertices[static_cast<std::size_t>(1 + 7 * 16)]) * 0.5; // the south and north poles of bead 1
    for (std::size_t i = 0; i < 1 + 7 * 16 + 1; ++i, ++total) outward += glm::dot(s.normals[i], s.vertices[i] - centre) > 0 ? 1 : 0;
    CHECK(outward == total);

    // dmFrameVoxelNormal: perpendicular to the world image of every voxel vector perpendicular
    // to nv, on the side of the mapped normal; on the plane (nv vpu) normalised.
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    for (int n = 0; n < 200; ++n) {
        const glm::dvec3 pS(U(rng), U(rng), U(rng)), pT(U(rng), U(rng), U(rng)), nn = glm::normalize(glm::cross(pS, pT) + 0.2 * glm::dvec3(U(rng), U(rng), U(rng)));
        const glm::dvec3 vpu(10 + 5 * U(rng), 12 + 5 * U(rng), 30 + 10 * U(rng));
        const glm::dvec3 nv = glm::normalize(glm::dvec3(U(rng), U(rng), U(rng)));
        const glm::dvec3 w = kern::dmFrameVoxelNormal(nv, pS, pT, nn, vpu);
        const auto world = [&](const glm::dvec3& q) { return pS * (q.x / vpu.x) + pT * (q.y / vpu.y) + nn * (q.z / vpu.z); };
        const glm::dvec3 a = glm::normalize(glm::cross(nv, glm::dvec3(0.3, 0.5, 0.7))), b = glm::cross(nv, a);
        CHECK(std::abs(glm::dot(w, world(a))) < 1e-9 * glm::length(world(a)));
        CHECK(std::abs(glm::dot(w, world(b))) < 1e-9 * glm::length(world(b)));
        CHECK(glm::dot(w, world(nv)) > 0); // the side nv points to
        CHECK(glm::length(w) == Approx(1.0).epsilon(1e-12));
    }
    {
        // A mirrored chart (pT flipped, the frame's determinant negative): the normal stays on
        // the side nv points to.
        const glm::dvec3 pS(1, 0.2, 0), pT(0.1, -1, 0), nn(0, 0, 1), vpu(10, 10, 30), nv = glm::normalize(glm::dvec3(0.2, 0.3, 1));
        const glm::dvec3 w = kern::dmFrameVoxelNormal(nv, pS, pT, nn, vpu);
        const glm::dvec3 up = pS * (nv.x / vpu.x) + pT * (nv.y / vpu.y) + nn * (nv.z / vpu.z);
        CHECK(glm::dot(w, up) > 0);
        CHECK(std::abs(glm::dot(w, pS * 0.3 / vpu.x - nn * (0.3 * nv.x / nv.z) / vpu.z)) < 1e-12); // perpendicular to a tangent
    }
    // dmSolidFacing: the face's normal towards the ray, the shading normal to its side.
    {
        glm::dvec3 n(0.1, 0, -1);
        const glm::dvec3 g = kern::dmSolidFacing(glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1), n); // seen from below
        CHECK(g == glm::dvec3(0, 0, -1));
        CHECK(n == glm::dvec3(0.1, 0, -1));
        glm::dvec3 m(0.1, 0, -1);
        CHECK(kern::dmSolidFacing(glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, -1), m) == glm::dvec3(0, 0, 1));
        CHECK(m == glm::dvec3(-0.1, 0, 1));
    }
    const glm::dvec3 nv(0.3, -0.4, 0.866), vpu(8, 4, 20);
    const glm::dvec3 plane = kern::dmFrameVoxelNormal(nv, glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1), vpu);
    const glm::dvec3 expect = glm::normalize(nv * vpu);
    CHECK(glm::length(plane - expect) < 1e-12);
}

} // namespace dmtest_meso

namespace dmtest_meso {

TEST_CASE("a box whose faces lie on voxel walls, its top on the slab's: the march finds every face", "[meso][solid]") {
    // An axis-aligned box, x and y in [3, 9], z in [2, 8] voxels, in 12 x 12 x 8 voxels: its
    // faces on voxel walls and its top on the slab's top z = 8. The reference is the ray against
    // the box in closed form (the slab method), not the voxels' lists.
    std::vector<glm::dvec3> v;
    for (int k = 0; k < 8; ++k) v.push_back({3.0 + 6 * (k & 1), 3.0 + 6 * ((k >> 1) & 1), 2.0 + 6 * (k >> 2)});
    const std::vector<std::array<int, 3>> t = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                                               {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    const MesoSolid s = mesoSolidFromMesh(v, t, 12, 12, 8, MesoSolidTile{{0, 0, 0}, 12.0});
    MesoMapOptions opt;
    opt.cones = ConeSet{4, 1, true, false};
    opt.distance = false;
    const MesoMaps maps = buildMesoSolidMaps(s, opt);
    const auto boxHit = [](const glm::dvec3& o, const glm::dvec3& d, double& tHit) { // the first entry into the box or the floor
        double t0 = 0, t1 = std::numeric_limits<double>::infinity();
        for (int a = 0; a < 3; ++a) {
            const double lo = a < 2 ? 3.0 : 2.0, hi = a < 2 ? 9.0 : 8.0;
            // The box repeats every 12 voxels in x and y: take the copy in o's tile.
            const double shift = a < 2 ? 12.0 * std::floor(o[a] / 12.0) : 0.0;
            if (d[a] == 0) {
                if (o[a] < lo + shift || o[a] > hi + shift) return false;
                continue;
            }
            double ta = (lo + shift - o[a]) / d[a], tb = (hi + shift - o[a]) / d[a];
            if (ta > tb) std::swap(ta, tb);
            t0 = std::max(t0, ta);
            t1 = std::min(t1, tb);
        }
        if (t0 > t1) return false;
        tHit = t0;
        return true;
    };
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    int tops = 0, walls = 0;
    for (int n = 0; n < 3000; ++n) {
        // Rays that stay in one tile's column of copies: steep enough to reach the floor within it.
        const bool up = n % 3 == 2;
        const glm::dvec3 o(1 + 10 * U(rng), 1 + 10 * U(rng), up ? 0.5 + 1.2 * U(rng) : 8.0);
        const double z = (up ? 1 : -1) * (0.85 + 0.15 * U(rng)), az = 6.283185307179586 * U(rng);
        const glm::vec3 df(glm::dvec3(std::sqrt(1 - z * z) * std::cos(az), std::sqrt(1 - z * z) * std::sin(az), z));
        const glm::dvec3 d(df), of{glm::vec3(o)};
        double tBox = 0;
        const bool box = boxHit(of, d, tBox);
        const MesoSolidHit h = marchDdmSolid<float>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, s, of, d, 1024, 1);
        INFO("o " << of.x << "," << of.y << "," << of.z << " d " << d.x << "," << d.y << "," << d.z);
        if (box) {
            REQUIRE(h.triangle >= 0);
            REQUIRE(h.t == Approx(tBox).margin(1e-4)); // float, t below 10
            tops += std::abs(of.z + tBox * d.z - 8.0) < 1e-6 ? 1 : 0;
            walls += !up && std::abs(of.z + tBox * d.z - 8.0) > 1e-3 ? 1 : 0;
        } else if (!up) {
            REQUIRE(h.triangle == -1); // the floor
        }
    }
    CHECK(tops > 300);  // the top on the slab's top is hit (it was listed nowhere before)
    CHECK(walls > 10);  // and the side walls on voxel walls
}

TEST_CASE("chain mail: a mesh that crosses the tile's side links the next tile's ring", "[meso][solid]") {
    // Ring A lies flat in the middle of a tile 3 units wide; ring B stands in the xz plane,
    // centred on the tile's side x = 3, through A's hole: B's copy from the tile before (x - 3)
    // passes through A's hole from the other side, so the rings chain along x.
    std::vector<glm::dvec3> v;
    std::vector<std::array<int, 3>> t;
    appendTorus({1.5, 1.5, 1.0}, {0, 0, 1}, 1.0, 0.25, 24, 10, v, t);
    appendTorus({3.0, 1.5, 1.0}, {0, 1, 0}, 1.0, 0.25, 24, 10, v, t);
    const MesoSolidTile tile{{0.0, 0.0, -0.5}, 3.0}; // the floor half a unit below B's lowest point
    const MesoSolid s = mesoSolidFromMesh(v, t, 24, 24, 24, tile);
    const double k = 24.0 / 3.0; // voxels a unit
    const auto solidAt = [&](glm::dvec3 p) { // p in mesh units
        const glm::dvec3 q = (p - tile.corner) * k * double(s.sub);
        return s.subSolid(static_cast<int>(std::floor(q.x)), static_cast<int>(std::floor(q.y)), static_cast<int>(std::floor(q.z)));
    };
    CHECK(solidAt({2.0, 1.5, 1.0}));   // B's tube inside A's hole (B itself)
    CHECK(solidAt({1.0, 1.5, 1.0}));   // B's copy from the tile before, inside A's hole from the other side
    CHECK(solidAt({3.0, 1.5, 2.0}));   // B's top on the side x = 3, i.e. x = 0 of this tile
    CHECK(solidAt({0.02, 1.5, 2.0}));
    CHECK(!solidAt({1.5, 1.5, 1.0}));  // the middle of A's hole is empty
    CHECK(!solidAt({1.5, 0.2, 2.0}));  // above A, away from B
    // Every corner normal points out of its ring's tube.
    for (std::size_t i = 0; i < s.vertices.size(); ++i) {
        const bool ringA = i < 240;
        const glm::dvec3 c = (ringA ? glm::dvec3(1.5, 1.5, 1.0) : glm::dvec3(3.0, 1.5, 1.0)) * k - tile.corner * k;
        const glm::dvec3 axis = ringA ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
        glm::dvec3 radial = s.vertices[i] - c - axis * glm::dot(s.vertices[i] - c, axis);
        radial = glm::normalize(radial) * k; // the centre circle's point (R = 1 unit)
        CHECK(glm::dot(s.normals[i], s.vertices[i] - (c + radial)) > 0);
    }
    // The march through copies across the seam finds the double reference's hits.
    MesoMapOptions opt;
    opt.cones = ConeSet{4, 1, true, false};
    opt.distance = false;
    const MesoMaps maps = buildMesoSolidMaps(s, opt);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    int same = 0, rings = 0;
    const int rays = 2000;
    for (int n = 0; n < rays; ++n) {
        const bool up = n % 4 == 3;
        const glm::dvec3 o(U(rng) * 72 - 24, U(rng) * 72 - 24, up ? U(rng) * 24 : 24.0);
        const double z = (0.02 + 0.98 * U(rng)) * (up ? 1 : -1), az = 6.283185307179586 * U(rng);
        const glm::dvec3 d(std::sqrt(1 - z * z) * std::cos(az), std::sqrt(1 - z * z) * std::sin(az), z);
        const MesoHit ref = marchSolidReference(s, o, d);
        const MesoSolidHit h = marchDdmSolid(CompressedDdmView{&maps.ddm}, maps.ddm.cones, s, o, d);
        INFO("o " << o.x << "," << o.y << "," << o.z << " d " << d.x << "," << d.y << "," << d.z);
        REQUIRE(h.hit == ref.hit);
        if (h.hit) REQUIRE(h.t == Approx(ref.t).margin(1e-9)); // both in double
        ++same;
        rings += h.triangle >= 0 ? 1 : 0;
    }
    CHECK(same == rays);
    CHECK(rings > rays / 4);
    // The tile's bad inputs.
    CHECK_THROWS_WITH(mesoSolidFromMesh(v, t, 24, 24, 24, MesoSolidTile{{0, 0, 0}, 0.0}), Catch::Contains("size > 0"));
    CHECK_THROWS_WITH(mesoSolidFromMesh(v, t, 24, 24, 8, tile), Catch::Contains("more than 8 layers"));
    CHECK_THROWS_WITH(mesoSolidFromMesh(v, t, 24, 24, 24, MesoSolidTile{{-20.0, 0, -0.5}, 3.0}), Catch::Contains("tiles beyond"));
    // Far below the floor (its voxel rows would be looped over, and overflow an int).
    CHECK_THROWS_WITH(mesoSolidFromMesh(v, t, 24, 24, 24, MesoSolidTile{{0.0, 0, 1e9}, 3.0}), Catch::Contains("below its floor"));
    // A voxel no pixel can afford: a fine sphere in a few voxels.
    std::vector<glm::dvec3> fine;
    std::vector<std::array<int, 3>> fineT;
    appendUvSphere({1, 1, 1}, 0.9, 48, fine, fineT);
    CHECK_THROWS_WITH(mesoSolidFromMesh(fine, fineT, 2, 2, 2, MesoSolidTile{{0, 0, 0}, 2.0}), Catch::Contains("crossed by more than 1024 triangles"));
    // A solid's maps are not a mesostructure file's.
    CHECK_THROWS_WITH(saveMesoMaps(maps, std::string(DISPMAP_TEST_BINARY_DIR) + "/solid.dmm"), Catch::Contains("height field's maps"));
}

} // namespace dmtest_meso

#include "dispmap/scene/meso.h"
#include "test_files.h"

namespace dmtest_meso {

TEST_CASE("a scene's mesh mesostructure: chain mail placed in its tile, and clear errors", "[meso][solid][scene]") {
    const std::string data = DISPMAP_TEST_DATA;
    const auto parse = [&](const std::string& json) { return parseMesoScene(nlohmann::json::parse(json), "c.json", data); };
    const MesoSceneDesc s = parse(R"({"mesostructure": {"mesh": "chainmail.obj", "meshTile": {"corner": [0, 0, -1.3], "size": 3},
                                     "size": 24, "layers": 24}, "effects": {"shadows": true}})");
    CHECK(s.mesh == (std::filesystem::path(data) / "chainmail.obj").string());
    REQUIRE(s.meshTile);
    const MesoMaps maps = buildMesoSceneMaps(s);
    REQUIRE(maps.isSolid());
    CHECK(maps.solid.triangles.size() == 1536); // 2 rings x 32 x 12 quads, two triangles each
    CHECK(maps.distance.d.empty());             // the DDM march needs no distance map
    CHECK(maps.ddm.cones.shadow);               // shadows: the shadow cones
    // The tile's corner is the mesh's (0, 0, -1.3): ring A's middle (1.5, 1.5, 0) is voxel
    // (12, 12, 10.4), empty (its hole); its tube at (2.5, 1.5, 0) is solid.
    CHECK(!maps.solid.subSolid(24, 24, 20));
    CHECK(maps.solid.subSolid(40, 24, 20));
    // Without meshTile the bounding box is fitted: the same rings, other voxels.
    const MesoMaps fitted = buildMesoSceneMaps(parse(R"({"mesostructure": {"mesh": "chainmail.obj", "size": 24, "layers": 24}})"));
    CHECK(fitted.solid.triangles.size() == 1536);
    CHECK(fitted.solid.entries.size() != maps.solid.entries.size());

    using Row = std::pair<const char*, const char*>;
    const std::vector<Row> rows = {
        {R"({"mesostructure": {"mesh": "chainmail.obj", "height": "x.png"}})", "no 'height' or 'function' beside it"},
        {R"({"mesostructure": {"mesh": "chainmail.obj", "function": "waves"}})", "no 'height' or 'function' beside it"},
        {R"({"mesostructure": {"mesh": "chainmail.obj", "depth": 4}})", "'mesostructure.depth' applies to a height field"},
        {R"({"mesostructure": {"mesh": "chainmail.obj", "normals": "height"}})", "'mesostructure.normals' applies to a height field"},
        {R"({"mesostructure": {"mesh": "chainmail.obj"}, "effects": {"technique": "relief"}})", "is marched by the DDM"},
        {R"({"mesostructure": {"mesh": "chainmail.obj", "size": 0}})", "'mesostructure.size' 0: a 'mesh' needs the voxels"},
        {R"({"mesostructure": {"meshTile": {"corner": [0, 0, 0], "size": 3}}})", "'mesostructure.meshTile' without 'mesostructure.mesh'"},
        {R"({"mesostructure": {"mesh": "chainmail.obj", "meshTile": {"size": 3}}})", "needs 'corner' [x, y, z] and 'size'"},
        {R"({"mesostructure": {"mesh": "chainmail.obj", "meshTile": {"corner": [0, 0, 0], "size": -1}}})", "must be > 0"},
        {R"({"mesostructure": {"mesh": "chainmail.obj", "meshTile": {"corner": [0, 0, 0], "size": 3, "scale": 2}}})", "scale"},
        {R"({"mesostructure": {"mesh": 7}})", "'mesostructure.mesh' must be a file name"},
        {R"({"mesostructure": {"mesh": "chainmail.obj", "size": 4096, "layers": 256}})", "MiB"},
    };
    for (const auto& [json, message] : rows) {
        INFO(json);
        CHECK_THROWS_WITH(parse(json), Catch::Contains("c.json: ") && Catch::Contains(message));
    }
    // Errors found when the mesh is read: a missing file, a mesh too tall for the layers.
    CHECK_THROWS_AS(buildMesoSceneMaps(parse(R"({"mesostructure": {"mesh": "no_such.obj"}})")), FileError);
    CHECK_THROWS_WITH(buildMesoSceneMaps(parse(R"({"mesostructure": {"mesh": "chainmail.obj", "meshTile": {"corner": [0, 0, -1.3], "size": 3},
                                                   "size": 24, "layers": 8}})")),
                      Catch::Contains("c.json: 'mesostructure.mesh': mesh mesostructure: the mesh is") && Catch::Contains("more than 8 layers"));
    dmtest::TempDir dir("dispmap_solid_");
    // An open mesh is a two-sided sheet (no inside; its triangles are still hit exactly): one
    // triangle tilted over the tile, its lowest corner on the floor.
    std::ofstream((dir.path / "open.obj").string()) << "v 0 0 0\nv 1 0 0.5\nv 0 1 0.5\nf 1 2 3\n";
    const auto inDir = [&](const std::string& json) { return parseMesoScene(nlohmann::json::parse(json), "c.json", dir.path.string()); };
    const MesoMaps sheet = buildMesoSceneMaps(inDir(R"({"mesostructure": {"mesh": "open.obj", "size": 8, "layers": 8}})"));
    const MesoSolidHit h = marchDdmSolid(CompressedDdmView{&sheet.ddm}, sheet.ddm.cones, sheet.solid, {2, 2, 8}, {0, 0, -1});
    CHECK(h.triangle == 0);
    // z = (x + y) / 2 in mesh units, 8 voxels a unit: voxel (2, 2) is (0.25, 0.25), z 0.25 units = 2 voxels.
    CHECK(h.t == Approx(8.0 - 2.0).margin(1e-9));
}

} // namespace dmtest_meso
