// Height maps placed through the mesh's UVs: smooth (face-varying) UVs against OpenSubdiv's own
// limit, maps baked on smooth UVs, UDIM sets, prefiltering, tile sizes from the texel density,
// and D across UV seams.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/tessellator.h"
#include "dispmap/surface/map_source.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/surface/tile_topology.h"
#include "dispmap/surface/uv_map.h"
#include "dispmap/io/png.h"
#include "test_support.h"

namespace dmtest_test_map_source {

using namespace dispmap;
using Catch::Contains;

namespace {

/// `mesh` with one texture coordinate per vertex, (x, y) of its position: no UV seams, so the
/// fully smooth face-varying rule subdivides the UVs exactly as the vertices.
ControlMesh withPositionUVs(const ControlMesh& mesh) {
    MeshDescription d = mesh.description();
    d.uvs.clear();
    for (const glm::dvec3& p : d.positions) d.uvs.emplace_back(p.x, p.y);
    d.faceUVs = d.faceVertices;
    return ControlMesh(d);
}

/// An image of h(s, t) at texel centres (row 0 at the top, t = 1).
std::shared_ptr<HeightImage> imageOf(int w, int hgt, double (*h)(double, double)) {
    auto img = std::make_shared<HeightImage>();
    img->width = w;
    img->height = hgt;
    for (int y = 0; y < hgt; ++y)
        for (int x = 0; x < w; ++x)
            img->values.push_back(static_cast<float>(h((x + 0.5) / w, 1.0 - (y + 0.5) / hgt)));
    return img;
}

double smoothHeight(double s, double t) { return 0.5 + 0.3 * std::sin(5.0 * s + 1.0) * std::cos(4.0 * t); }

/// A 6 x 6 grid in the plane whose interior UVs are pushed about, so that the smooth and the
/// linear UV layouts differ by about 5e-3 (and no face folds over).
ControlMesh warpedGrid() {
    MeshDescription d = parseObj(dmtest::gridObj(6, 6), "warped grid");
    for (std::size_t i = 0; i < d.uvs.size(); ++i) {
        glm::dvec2& t = d.uvs[i];
        if (t.x > 0 && t.x < 1 && t.y > 0 && t.y < 1) t += 0.06 * glm::dvec2(std::sin(9.0 * static_cast<double>(i)), std::cos(7.0 * static_cast<double>(i)));
    }
    return ControlMesh(d);
}

/// max |D(tiles) - ref| over an 8 x 8 grid of points of every tile (finest level).
template <typename F> double maxError(const TileSet& ts, F ref) {
    double e = 0.0;
    for (int t = 0; t < ts.tileCount(); ++t)
        for (int j = 0; j < 8; ++j)
            for (int i = 0; i < 8; ++i) {
                const glm::dvec2 uv((i + 0.5) / 8, (j + 0.5) / 8);
                e = std::max(e, std::abs(ts.evaluate<double>(t, 0, uv) - ref(t, uv.x, uv.y)));
            }
    return e;
}

} // namespace

TEST_CASE("smooth UVs: OpenSubdiv's face-varying limit, equal to the vertex limit when the UVs have no seams", "[uvmap]") {
    for (const char* name : {"catmark_cube", "catmark_pyramid", "catmark_toroidal_tet", "catmark_pole8"}) {
        INFO(name);
        const ControlMesh mesh = withPositionUVs(dmtest::shape(name));
        const UvMap uvs(mesh, UvInterpolation::Smooth);
        REQUIRE(uvs.smooth());
        const BaseSurface base(mesh);
        const Far::TopologyLevel& L = mesh.base();
        double regular = 0.0, irregular = 0.0, derivRegular = 0.0, derivIrregular = 0.0;
        for (int t = 0; t < mesh.ptexFaceCount(); ++t) {
            const int f = uvs.baseFace(t);
            bool ev = L.GetFaceVertices(f).size() != 4;
            for (int v : L.GetFaceVertices(f)) ev = ev || L.GetVertexFaces(v).size() != 4;
            for (int j = 0; j <= 4; ++j)
                for (int i = 0; i <= 4; ++i) {
                    const double u = i / 4.0, v = j / 4.0;
                    const UvSample s = uvs.evaluate(t, u, v);
                    const BaseSample<double> b = base.evaluate(t, u, v, true);
                    const double e = glm::length(s.uv - glm::dvec2(b.p.x, b.p.y));
                    (ev ? irregular : regular) = std::max(ev ? irregular : regular, e);
                    // derivatives against central differences (h = 1e-5: error ~1e-10 for a cubic)
                    const double h = 1e-5, uc = std::clamp(u, h, 1 - h), vc = std::clamp(v, h, 1 - h);
                    const UvSample c = uvs.evaluate(t, uc, vc);
                    const glm::dvec2 fu = (uvs(t, uc + h, vc) - uvs(t, uc - h, vc)) / (2 * h);
                    const glm::dvec2 fv = (uvs(t, uc, vc + h) - uvs(t, uc, vc - h)) / (2 * h);
                    double& deriv = ev ? derivIrregular : derivRegular;
                    deriv = std::max({deriv, glm::length(c.du - fu), glm::length(c.dv - fv)});
                }
        }
        // Faces of regular vertices: both are the same bicubic B-spline patch (rounding only).
        CHECK(regular < 1e-12);
        // At extraordinary vertices Bfr and the base surface's Far patch table approximate the
        // limit differently (Bfr's own irregular patches, Far's end caps at the isolation level):
        // measured up to 9e-3 (catmark_pole8, size ~2).
        CHECK(irregular < 2e-2);
        // Central differences of a bicubic: h^2 |f'''| / 6 plus rounding ~1e-16 / h.
        CHECK(derivRegular < 1e-6);
        // Bfr's irregular surfaces are piecewise (patches of its adaptive approximation, C1
        // only in the limit), so differences straddling their joins see a small kink:
        // measured 3e-3 on the pyramid.
        CHECK(derivIrregular < 1e-2);
    }
}

TEST_CASE("linear UVs are each face's bilinear corners, sub-faces of N-gons included", "[uvmap]") {
    const ControlMesh mesh = withPositionUVs(dmtest::shape("catmark_nonquads"));
    const UvMap uvs(mesh, UvInterpolation::Linear);
    REQUIRE_FALSE(uvs.smooth());
    // Face-varying linear interpolation in Bfr (FVAR_LINEAR_ALL) is the same thing.
    MeshDescription d = mesh.description();
    d.fvarLinear = Sdc::Options::FVAR_LINEAR_ALL;
    const ControlMesh same(d);
    const std::unique_ptr<Far::TopologyRefiner> r = same.createRefiner(Sdc::Options::FVAR_LINEAR_ALL);
    Bfr::RefinerSurfaceFactory<>::Options fo;
    fo.SetDefaultFVarID(0);
    const Bfr::RefinerSurfaceFactory<> factory(*r, fo);
    double e = 0.0;
    for (int t = 0; t < mesh.ptexFaceCount(); ++t) {
        Bfr::Surface<double> s;
        REQUIRE(factory.InitFaceVaryingSurface(uvs.baseFace(t), &s));
        std::vector<double> pp(2 * static_cast<std::size_t>(s.GetNumPatchPoints()));
        const Bfr::Surface<double>::PointDescriptor pd(2);
        s.PreparePatchPoints(&d.uvs[0].x, pd, pp.data(), pd);
        const int first = mesh.ptex().GetFaceId(uvs.baseFace(t));
        for (int j = 0; j <= 3; ++j)
            for (int i = 0; i <= 3; ++i) {
                double in[2] = {i / 3.0, j / 3.0}, coord[2] = {in[0], in[1]}, p[2];
                if (s.GetFaceSize() != 4) s.GetParameterization().ConvertNormalizedSubFaceToCoord(t - first, in, coord);
                s.Evaluate(coord, pp.data(), pd, p);
                e = std::max(e, glm::length(uvs(t, in[0], in[1]) - glm::dvec2(p[0], p[1])));
            }
    }
    CHECK(e < 1e-12); // the same bilinear interpolation, rounding only
    REQUIRE_THROWS_WITH(UvMap(ControlMesh::fromObjText(dmtest::torusObj(4, 4), "torus")), Contains("no texture coordinates"));
    CHECK(parseUvInterpolation("corners+1") == UvInterpolation::CornersPlus1);
    CHECK_FALSE(parseUvInterpolation("smoooth"));
}

TEST_CASE("a map baked on smooth UVs lands where the function says only under smooth UVs", "[mapsource]") {
    const ControlMesh mesh = warpedGrid();
    HeightMaps maps;
    maps.images[0] = imageOf(1024, 1024, smoothHeight);
    const std::vector<int> k = uniformTileSizes(mesh, 5);
    const auto smooth = std::make_shared<const UvMap>(mesh, UvInterpolation::Smooth);
    const auto linear = std::make_shared<const UvMap>(mesh, UvInterpolation::Linear);
    const auto truth = [&](int t, double u, double v) {
        const glm::dvec2 p = (*smooth)(t, u, v);
        return smoothHeight(p.x, p.y);
    };
    MapSourceOptions o;
    double layouts = 0.0; // how far apart the two layouts are
    for (int t = 0; t < mesh.ptexFaceCount(); ++t)
        layouts = std::max(layouts, glm::length((*smooth)(t, 0.5, 0.5) - (*linear)(t, 0.5, 0.5)));
    REQUIRE(layouts > 3e-3);
    const double eSmooth = maxError(buildTiles(mesh, k, mapSource(smooth, maps, k, o)), truth);
    const double eLinear = maxError(buildTiles(mesh, k, mapSource(linear, maps, k, o)), truth);
    // Smooth: the image's bilinear reconstruction (h'' / 8 texel^2 ~ 1e-6) plus the fit between
    // samples of a 32-texel tile (|h''| (1/192)^2 / 8 ~ 4e-5 here) and float texels (3e-8).
    CHECK(eSmooth < 2e-4);
    // Linear: off by the layouts' distance times |grad h| (~1.5): measured 30x more.
    CHECK(eLinear > 10 * eSmooth);
}

TEST_CASE("tiles written back into UV space reproduce the map they were built from", "[mapsource]") {
    const ControlMesh mesh = warpedGrid();
    HeightMaps maps;
    maps.images[0] = imageOf(256, 256, smoothHeight);
    const std::vector<int> k = uniformTileSizes(mesh, 5);
    const auto uvs = std::make_shared<const UvMap>(mesh, UvInterpolation::Smooth);
    MapSourceOptions o;
    o.scale = 0.2;
    o.offset = 0.01;
    o.midLevel = 0.5;
    const TileSet ts = buildTiles(mesh, k, mapSource(uvs, maps, k, o));
    std::vector<std::uint8_t> covered;
    const HeightImage back = tilesToMap(*uvs, ts, 0, 256, 256, o.scale, o.offset, o.midLevel, &covered);
    double inner = 0.0, border = 0.0;
    std::size_t n = 0;
    for (int y = 0; y < 256; ++y)
        for (int x = 0; x < 256; ++x) {
            const std::size_t i = static_cast<std::size_t>(y * 256 + x);
            n += covered[i];
            const double e = covered[i] ? std::abs(static_cast<double>(back.values[i]) - static_cast<double>(maps.images[0]->values[i])) : 0.0;
            (x < 4 || y < 4 || x >= 252 || y >= 252 ? border : inner) = std::max(x < 4 || y < 4 || x >= 252 || y >= 252 ? border : inner, e);
        }
    // The smooth rule rounds the square's four corners off (a boundary corner is not
    // interpolated, as for vertices): measured 99.1 % of the texels covered.
    CHECK(n > back.values.size() * 98 / 100);
    // Inside: the fit between samples 4/3 texels apart (h^2 |h''| / 8 ~ 1e-5) and float texels.
    CHECK(inner < 1e-4); // measured 3.4e-5
    // Within 4 texels of the border the tiles extrapolate past the last sample centre.
    CHECK(border < 1e-3);
    REQUIRE_THROWS_WITH(tilesToMap(*uvs, ts, 0, 0, 256, 1.0, 0.0, 0.0), Contains("out of range"));
    // Spot's UVs reach 5 % past [0, 1]: with wrap those parts land on the other side.
    const ControlMesh spot = dmtest::shape("spot_control_mesh");
    const UvMap spotUvs(spot, UvInterpolation::Linear);
    const TileSet flat = buildTiles(spot, uniformTileSizes(spot, 2), [](int, double, double) { return 1.0; });
    std::vector<std::uint8_t> plain, wrapped;
    (void)tilesToMap(spotUvs, flat, 0, 128, 128, 1.0, 0.0, 0.0, &plain);
    const HeightImage w = tilesToMap(spotUvs, flat, 0, 128, 128, 1.0, 0.0, 0.0, &wrapped, true);
    CHECK(std::count(wrapped.begin(), wrapped.end(), 1) > std::count(plain.begin(), plain.end(), 1));
    for (std::size_t i = 0; i < wrapped.size(); ++i)
        if (wrapped[i]) REQUIRE(std::abs(w.values[i] - 1.0f) < 1e-6f); // D = 1 everywhere, rounding of the fit only
    REQUIRE_THROWS_WITH(tilesToMap(*uvs, ts, 0, 16, 16, 0.0, 0.0, 0.0), Contains("scale"));
}

TEST_CASE("UDIM sets: each face reads its own tile; missing tiles and faces across tiles are errors", "[mapsource]") {
    // A 2 x 1 grid: face 1 in UDIM 1001, face 2 in 1002 (u in [1, 2]).
    const std::string obj = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\n"
                            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 1 0\nvt 2 0\nvt 2 1\nvt 1 1\n"
                            "f 1/1 2/2 5/3 4/4\nf 2/5 3/6 6/7 5/8\n";
    const ControlMesh mesh = ControlMesh::fromObjText(obj, "udim grid");
    const auto uvs = std::make_shared<const UvMap>(mesh, UvInterpolation::Linear);
    const auto flat = [](float value) {
        auto img = std::make_shared<HeightImage>();
        img->width = img->height = 4;
        img->values.assign(16, value);
        return img;
    };
    HeightMaps maps;
    maps.udim = true;
    maps.images[1001] = flat(0.25f);
    maps.images[1002] = flat(0.75f);
    const DisplacementFunction src = mapSource(uvs, maps, {}, MapSourceOptions{});
    CHECK(src(0, 0.5, 0.5) == 0.25);
    CHECK(src(1, 0.5, 0.5) == 0.75);
    CHECK(src(1, 0.0, 0.0) == 0.75); // its corner on the tile border still reads its own tile
    // written back per tile: each tile's square holds its own face
    const TileSet ts = buildTiles(mesh, uniformTileSizes(mesh, 4), src);
    std::vector<std::uint8_t> covered;
    const HeightImage second = tilesToMap(*uvs, ts, 1002, 8, 8, 1.0, 0.0, 0.0, &covered);
    CHECK(std::all_of(covered.begin(), covered.end(), [](std::uint8_t c) { return c == 1; }));
    // D is continuous, so it climbs from 0.25 to 0.75 across the shared edge (u = 0 of this
    // tile); 13 samples away the ringing has decayed (0.17 a sample): measured < 1e-6.
    CHECK(std::abs(second.values[3 * 8 + 6] - 0.75f) < 1e-4f);
    HeightMaps missing = maps;
    missing.images.erase(1002);
    missing.images[1011] = flat(0.5f);
    REQUIRE_THROWS_WITH(mapSource(uvs, missing, {}, MapSourceOptions{}),
                        Contains("face 2 lies in UDIM tile 1002, which the set does not have (it has 1001, 1011)"));
    // one face across the border of 1001 and 1002
    const ControlMesh across = ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0.5 0\nvt 1.5 0\nvt 1.5 1\nvt 0.5 1\n"
                                                       "f 1/1 2/2 3/3 4/4\n",
                                                       "across");
    REQUIRE_THROWS_WITH(mapSource(std::make_shared<const UvMap>(across, UvInterpolation::Linear), maps, {}, MapSourceOptions{}),
                        Contains("spans UDIM tiles"));
    MapSourceOptions wrap;
    wrap.wrap = true;
    REQUIRE_THROWS_WITH(mapSource(uvs, maps, {}, wrap), Contains("wrapping does not apply"));
}

TEST_CASE("overlapping UVs are refused unless allowed; a shared UV edge is not an overlap", "[mapsource]") {
    HeightMaps maps;
    maps.images[0] = imageOf(64, 64, smoothHeight);
    // The grid's faces share edges in UV space: no overlap.
    const ControlMesh grid = ControlMesh::fromObjText(dmtest::gridObj(4, 3), "grid");
    REQUIRE_NOTHROW(mapSource(std::make_shared<const UvMap>(grid, UvInterpolation::Linear), maps, {}, MapSourceOptions{}));
    REQUIRE_NOTHROW(mapSource(std::make_shared<const UvMap>(grid, UvInterpolation::Smooth), maps, {}, MapSourceOptions{}));
    // Two faces on the same UV square (a mirrored half).
    const ControlMesh twice = ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\n"
                                                      "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                                      "f 1/1 2/2 5/3 4/4\nf 2/1 3/2 6/3 5/4\n",
                                                      "twice");
    const auto uvs = std::make_shared<const UvMap>(twice, UvInterpolation::Linear);
    REQUIRE_THROWS_WITH(mapSource(uvs, maps, {}, MapSourceOptions{}), Contains("faces 1 and 2 overlap in UV space"));
    MapSourceOptions allow;
    allow.allowOverlap = true;
    REQUIRE_NOTHROW(mapSource(uvs, maps, {}, allow));
}

TEST_CASE("smooth UVs on N-gons next to quads: the shared edges are no overlap", "[mapsource]") {
    // A pentagon (left) beside two quads: each quad edge meets half of a pentagon sub-face's
    // edge pair, and the UVs, pushed off the grid, make the smooth edges curve there.
    const ControlMesh mesh = ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 1 0.5 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 0.5 0\nv 2 1 0\n"
                                                      "vt 0.02 0.03\nvt 0.55 0.02\nvt 0.6 0.5\nvt 0.52 0.97\nvt 0.01 0.98\n"
                                                      "vt 0.98 0.01\nvt 0.96 0.41\nvt 0.99 0.99\n"
                                                      "f 1/1 2/2 3/3 4/4 5/5\nf 2/2 6/6 7/7 3/3\nf 3/3 7/7 8/8 4/4\n",
                                                      "pentagon and quads");
    HeightMaps maps;
    maps.images[0] = imageOf(2048, 2048, smoothHeight);
    for (UvInterpolation rule : {UvInterpolation::Linear, UvInterpolation::Smooth, UvInterpolation::Boundaries})
        REQUIRE_NOTHROW(mapSource(std::make_shared<const UvMap>(mesh, rule), maps, {}, MapSourceOptions{}));
}

TEST_CASE("prefiltering: a map finer than the tiles is integrated over each sample's footprint", "[mapsource]") {
    // Detail of period 1/64 on a 4 x 4 grid with 8-texel tiles: 32 samples across the map, so a
    // point sample aliases the 64-cycle stripes; their mean over a sub-patch (two periods), 0.5,
    // is what the tile can hold. The map repeats (wrap), so the tent's reach past the mesh
    // border sees stripes too.
    static constexpr auto stripes = [](double s, double) { return 0.5 + 0.4 * std::sin(2 * 3.14159265358979 * 64 * s + 1.0); };
    const ControlMesh grid = ControlMesh::fromObjText(dmtest::gridObj(4, 4), "grid");
    HeightMaps maps;
    maps.images[0] = imageOf(1024, 1024, +[](double s, double t) { return stripes(s, t); });
    const std::vector<int> k = uniformTileSizes(grid, 3);
    const auto uvs = std::make_shared<const UvMap>(grid, UvInterpolation::Linear);
    // The sub-patch mean of the stripes is 0.5 (an integer number of periods per sample).
    const auto mean = [](int, double, double) { return 0.5; };
    MapSourceOptions o;
    o.wrap = true;
    double err[3];
    for (MapFilter f : {MapFilter::Point, MapFilter::Box, MapFilter::Tent}) {
        o.filter = f;
        const DisplacementFunction src = mapSource(uvs, maps, k, o);
        double e = 0.0;
        for (int t = 0; t < grid.ptexFaceCount(); ++t)
            for (int j = 0; j < 8; ++j)
                for (int i = 0; i < 8; ++i) e = std::max(e, std::abs(src(t, (i + 0.5) / 8, (j + 0.5) / 8) - mean(t, (i + 0.5) / 8, (j + 0.5) / 8)));
        err[static_cast<int>(f)] = e;
    }
    CHECK(err[0] > 0.3);  // point: the centres all hit the stripes' phase 1 rad: 0.4 sin 1 = 0.34
    CHECK(err[1] < 2e-3); // box: 2 periods per sample integrated by 32 taps of the bilinear map
    CHECK(err[2] < 2e-3); // tent: the same, the stripes average out under it too
    // A map coarser than the tiles: every filter is the point sample.
    HeightMaps coarse;
    coarse.images[0] = imageOf(16, 16, smoothHeight);
    o.filter = MapFilter::Point;
    const DisplacementFunction p = mapSource(uvs, coarse, k, o);
    o.filter = MapFilter::Tent;
    const DisplacementFunction q = mapSource(uvs, coarse, k, o);
    double diff = 0.0;
    for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i) diff = std::max(diff, std::abs(p(5, (i + 0.5) / 8, (j + 0.5) / 8) - q(5, (i + 0.5) / 8, (j + 0.5) / 8)));
    CHECK(diff < 0.02); // the tent's two taps per axis straddle the centre of a smooth bilinear map
}

TEST_CASE("tile sizes from the texel density, and a mixed-size build from them", "[mapsource]") {
    // The grid's UVs cover the image; the map is 256 texels wide, 4 faces across: 64 texels per face.
    const ControlMesh grid = ControlMesh::fromObjText(dmtest::gridObj(4, 4), "grid");
    const UvMap uvs(grid, UvInterpolation::Linear);
    HeightMaps maps;
    maps.images[0] = imageOf(256, 64, smoothHeight); // 64 x 16 texels per face: k = 6 (max of the two)
    std::vector<int> k = texelTileSizes(grid, uvs, maps, 2, 8);
    CHECK(std::all_of(k.begin(), k.end(), [](int x) { return x == 6; }));
    k = texelTileSizes(grid, uvs, maps, 2, 5);
    CHECK(std::all_of(k.begin(), k.end(), [](int x) { return x == 5; }));
    // Spot: faces of different UV sizes get different k, and the mixed tiles build.
    const ControlMesh spot = dmtest::shape("spot_control_mesh");
    HeightMaps brick;
    brick.images[0] = std::make_shared<const HeightImage>(readHeightPng(dmtest::dataPath("skimage_brick.png")));
    const auto spotUvs = std::make_shared<const UvMap>(spot, UvInterpolation::Linear);
    k = texelTileSizes(spot, *spotUvs, brick, 1, 6);
    const auto [lo, hi] = std::minmax_element(k.begin(), k.end());
    CHECK(*lo < *hi);
    MapSourceOptions o;
    o.filter = MapFilter::Box;
    o.wrap = true; // Spot's UVs reach 5 % outside [0, 1]
    BuildReport rep;
    REQUIRE_NOTHROW(buildTiles(spot, k, mapSource(spotUvs, brick, k, o), {}, &rep));
    REQUIRE_THROWS_WITH(texelTileSizes(spot, *spotUvs, brick, 0, 6), Contains("out of range"));
}

TEST_CASE("tile sizes from a fit-error bound: flat parts get small tiles, the bound holds", "[mapsource]") {
    // coarsestTileWithin on its own: the chosen size's samples reproduce the fine ones within
    // the tolerance, and one size smaller would not (unless it is the smallest allowed).
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> noise(-1.0, 1.0);
    for (int trial = 0; trial < 20; ++trial) {
        const int kMax = 5, sf = 1 << kMax;
        std::vector<double> fine(static_cast<std::size_t>(sf * sf));
        const double wiggle = 0.02 * trial;
        for (int j = 0; j < sf; ++j)
            for (int i = 0; i < sf; ++i)
                fine[static_cast<std::size_t>(j * sf + i)] = std::sin(0.2 * i) * std::cos(0.15 * j) + wiggle * noise(rng);
        const double tolerance = 0.05;
        // the interpolation error of size kk's box means against the fine samples
        const auto errorAt = [&](int kk) {
            std::vector<double> copy = fine;
            return coarsestTileWithin(copy, kMax, 1e300, kk) == kk ? copy : std::vector<double>{};
        };
        std::vector<double> samples = fine;
        const int k = coarsestTileWithin(samples, kMax, tolerance, 2);
        REQUIRE(samples.size() == static_cast<std::size_t>(1 << (2 * k)));
        CHECK(samples == errorAt(k));
        const auto maxError = [&](const std::vector<double>& coarse, int kk) {
            const int s = 1 << kk, r = sf / s;
            double e = 0.0;
            for (int j = 0; j < sf; ++j)
                for (int i = 0; i < sf; ++i) {
                    const double x = std::clamp((i + 0.5) / r - 0.5, 0.0, s - 1.0), y = std::clamp((j + 0.5) / r - 0.5, 0.0, s - 1.0);
                    const int x0 = std::min(static_cast<int>(x), s - 2), y0 = std::min(static_cast<int>(y), s - 2);
                    const double fx = x - x0, fy = y - y0;
                    const auto at = [&](int a, int b) { return coarse[static_cast<std::size_t>(b * s + a)]; };
                    const double v = (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) + fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1));
                    e = std::max(e, std::abs(v - fine[static_cast<std::size_t>(j * sf + i)]));
                }
            return e;
        };
        INFO("trial " << trial << ": k " << k);
        if (k < kMax) CHECK(maxError(samples, k) <= tolerance);
        if (k > 2) CHECK(maxError(errorAt(k - 1), k - 1) > tolerance);
    }

    // On a mesh: a map flat on its left half and rippled on its right; faces over the ripples
    // keep the largest size, those over the flat half step down one level per face away from
    // them (the balance rule) to the smallest.
    const ControlMesh grid = ControlMesh::fromObjText(dmtest::gridObj(4, 4), "grid");
    const auto uvs = std::make_shared<const UvMap>(grid, UvInterpolation::Linear);
    HeightMaps maps;
    maps.images[0] = imageOf(256, 256, [](double u, double v) { return u < 0.5 ? 0.5 : 0.5 + 0.4 * std::sin(40.0 * u) * std::sin(30.0 * v); });
    MapSourceOptions o;
    o.filter = MapFilter::Box;
    const std::vector<int> k = errorTileSizes(grid, uvs, maps, 1, 5, 0.01, o);
    for (int t = 0; t < grid.ptexFaceCount(); ++t) {
        const double u = (*uvs)(t, 0.5, 0.5).x;
        INFO("face " << t << " at u " << u);
        CHECK(k[static_cast<std::size_t>(t)] == (u > 0.5 ? 5 : u > 0.25 ? 4 : 3));
    }
    const std::vector<int> flat = errorTileSizes(ControlMesh::fromObjText(dmtest::gridObj(1, 1), "one face"),
                                                 std::make_shared<const UvMap>(ControlMesh::fromObjText(dmtest::gridObj(1, 1), "one face"),
                                                                               UvInterpolation::Linear),
                                                 [] {
                                                     HeightMaps m;
                                                     m.images[0] = imageOf(64, 64, [](double, double) { return 0.25; });
                                                     return m;
                                                 }(),
                                                 1, 5, 0.01, o);
    CHECK(flat == std::vector<int>{1}); // a flat map: the smallest tile
    BuildReport rep;
    REQUIRE_NOTHROW(buildTiles(grid, k, mapSource(uvs, maps, k, o), {}, &rep));
    // Spot's N-gons pin their sub-faces (k - 1) and the quads next to them (k).
    const ControlMesh spot = dmtest::shape("spot_control_mesh");
    HeightMaps brick;
    brick.images[0] = std::make_shared<const HeightImage>(readHeightPng(dmtest::dataPath("skimage_brick.png")));
    const auto spotUvs = std::make_shared<const UvMap>(spot, UvInterpolation::Linear);
    o.wrap = true;
    const std::vector<int> loose = errorTileSizes(spot, spotUvs, brick, 1, 5, 10.0, o);
    const std::vector<char> pinned = quadsPinnedByNonQuads(spot);
    const Far::TopologyLevel& L = spot.base();
    int smallest = 5;
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        const int t = spot.ptex().GetFaceId(f);
        const bool quad = L.GetFaceVertices(f).size() == 4;
        if (!quad) CHECK(loose[static_cast<std::size_t>(t)] == 4);
        if (quad && pinned[static_cast<std::size_t>(f)]) CHECK(loose[static_cast<std::size_t>(t)] == 5);
        if (quad) smallest = std::min(smallest, loose[static_cast<std::size_t>(t)]);
    }
    CHECK(smallest == 1);
    // Balanced: neighbours one level apart at most (a sub-face's k + 1 is a quad's k).
    const TileTopology topo(spot);
    for (int t = 0; t < topo.tileCount(); ++t)
        for (int e = 0; e < 4; ++e)
            for (const TileTopology::Link& l : topo.links(t, e))
                CHECK(std::abs(loose[static_cast<std::size_t>(t)] + topo.scale(t) - loose[static_cast<std::size_t>(l.tile)] - topo.scale(l.tile)) <= 1);
    CHECK_THROWS_WITH(errorTileSizes(spot, spotUvs, brick, 1, 5, 0.0, o), Contains("tolerance"));
    CHECK_THROWS_WITH(errorTileSizes(spot, spotUvs, brick, 1, 5, std::nan(""), o), Contains("tolerance"));
    CHECK_THROWS_WITH(errorTileSizes(spot, spotUvs, brick, 6, 5, 0.1, o), Contains("out of range"));
    // A NaN sample never lets a tile shrink; a sample count that does not fit is refused.
    std::vector<double> withNan(16, 0.5);
    withNan[5] = std::nan("");
    CHECK(coarsestTileWithin(withNan, 2, 1.0, 1) == 2);
    std::vector<double> wrongCount(15, 0.5);
    CHECK_THROWS_WITH(coarsestTileWithin(wrongCount, 2, 1.0, 1), Contains("15 samples"));
}

TEST_CASE("D is continuous across UV seams although the map is not", "[mapsource]") {
    // Spot's UV layout has seams: the two faces of a seam edge read different charts of the
    // brick map, so the samples jump there; the tiles' shared overlap makes D continuous.
    const ControlMesh spot = dmtest::shape("spot_control_mesh");
    HeightMaps brick;
    brick.images[0] = std::make_shared<const HeightImage>(readHeightPng(dmtest::dataPath("skimage_brick.png")));
    const auto uvs = std::make_shared<const UvMap>(spot, UvInterpolation::Smooth);
    MapSourceOptions o;
    o.allowOverlap = true;
    o.filter = MapFilter::Box;
    const std::vector<int> k = uniformTileSizes(spot, 4);
    const DisplacementFunction src = mapSource(uvs, brick, k, o);
    const TileSet ts = buildTiles(spot, k, src);
    const TileTopology topo(spot);
    const MeshDescription& d = spot.description();
    double sourceJump = 0.0, tileJump = 0.0;
    int seamEdges = 0;
    for (int t = 0; t < topo.tileCount(); ++t)
        for (int e = 0; e < 4; ++e)
            for (const TileTopology::Link& l : topo.links(t, e)) {
                if (l.beta != 1.0) continue;
                // a seam: the two faces name different UVs at the shared corner
                const int fa = topo.baseFace(t), fb = topo.baseFace(l.tile);
                const int va = topo.cornerVertex(t, e);
                int ua = -1, ub = -1;
                for (int j = 0; j < d.faceSizes[static_cast<std::size_t>(fa)]; ++j)
                    if (d.faceVertices[static_cast<std::size_t>(spot.faceOffset(fa) + j)] == va) ua = d.faceUVs[static_cast<std::size_t>(spot.faceOffset(fa) + j)];
                for (int j = 0; j < d.faceSizes[static_cast<std::size_t>(fb)]; ++j)
                    if (d.faceVertices[static_cast<std::size_t>(spot.faceOffset(fb) + j)] == va) ub = d.faceUVs[static_cast<std::size_t>(spot.faceOffset(fb) + j)];
                if (ua < 0 || ub < 0 || ua == ub) continue;
                ++seamEdges;
                for (int i = 1; i < 8; ++i) {
                    const double y = i / 8.0, z = l.alpha - l.beta * y;
                    const glm::dvec2 pa = dmtest::edgePoint(e, y), pb = dmtest::edgePoint(l.edge, z);
                    sourceJump = std::max(sourceJump, std::abs(src(t, pa.x, pa.y) - src(l.tile, pb.x, pb.y)));
                    tileJump = std::max(tileJump, std::abs(ts.evaluate<double>(t, 0, pa) - ts.evaluate<double>(l.tile, 0, pb)));
                }
            }
    REQUIRE(seamEdges > 10);
    CHECK(sourceJump > 0.05);  // different charts of the bricks: measured 0.40 of the [0, 1] heights
    CHECK(tileJump < 1e-6);    // the shared ring: float coefficients, rounding only
}

TEST_CASE("a tessellation gets its UVs, its vertices split at UV seams", "[mapsource]") {
    const ControlMesh spot = dmtest::shape("spot_control_mesh");
    const TileSet ts = buildTiles(spot, uniformTileSizes(spot, 2), [](int, double, double) { return 0.0; });
    const BaseSurface base(spot);
    const DisplacedSurface surface(base, ts);
    const TriangleMesh m = tessellate(surface, uniformTessFactors(base, 2.0));
    for (UvInterpolation rule : {UvInterpolation::Linear, UvInterpolation::Smooth}) {
        const UvMap uvs(spot, rule);
        const TexturedMesh tm = texturedMesh(m, uvs);
        REQUIRE(tm.texcoords.size() == tm.mesh.positions.size());
        CHECK(tm.mesh.positions.size() > m.positions.size()); // Spot has seams
        CHECK(tm.mesh.triangles.size() == m.triangles.size());
        double uvErr = 0.0, posErr = 0.0;
        for (std::size_t j = 0; j < m.triangles.size(); ++j)
            for (int c = 0; c < 3; ++c) {
                const int v = tm.mesh.triangles[j][c];
                const glm::dvec2 q = m.triangleUVs[j][static_cast<std::size_t>(c)];
                uvErr = std::max(uvErr, glm::length(tm.texcoords[static_cast<std::size_t>(v)] - uvs(m.triangleFaces[j], q.x, q.y)));
                posErr = std::max(posErr, glm::length(tm.mesh.positions[static_cast<std::size_t>(v)] -
                                                      m.positions[static_cast<std::size_t>(m.triangles[j][c])]));
            }
        CHECK(uvErr <= 1e-9); // the copy's UV is the corner's, within the merge tolerance
        CHECK(posErr == 0.0);  // copies sit exactly where the vertex was
        // Only real seams split: the copies of one vertex hold UVs of different charts, far
        // more apart than rounding (a spurious split would differ by ~1e-15).
        std::vector<std::vector<glm::dvec2>> copies(m.positions.size());
        for (std::size_t j = 0; j < m.triangles.size(); ++j)
            for (int c = 0; c < 3; ++c) {
                auto& list = copies[static_cast<std::size_t>(m.triangles[j][c])];
                const glm::dvec2 t = tm.texcoords[static_cast<std::size_t>(tm.mesh.triangles[j][c])];
                if (std::find(list.begin(), list.end(), t) == list.end()) list.push_back(t);
            }
        double closest = 1.0;
        for (const auto& list : copies)
            for (std::size_t a = 0; a < list.size(); ++a)
                for (std::size_t b = a + 1; b < list.size(); ++b) closest = std::min(closest, glm::length(list[a] - list[b]));
        CHECK(closest > 1e-4);
    }
}

} // namespace dmtest_test_map_source
