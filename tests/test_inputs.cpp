// Bad inputs get a clear error, and real sources (UV-mapped height images) go through.
#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>

#include <opensubdiv/far/error.h>

#include "dispmap/io/png.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/surface/map_source.h"
#include "test_files.h"
#include "test_support.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_inputs {

using namespace dispmap;
using Catch::Contains;

TEST_CASE("malformed and non-manifold meshes are rejected with the offending element named", "[inputs]") {
    REQUIRE_THROWS_AS(dmtest::shape("catmark_fan"), MeshError); // three faces on one edge
    REQUIRE_THROWS_WITH(dmtest::shape("catmark_fan"), Contains("non-manifold edge"));
    REQUIRE_THROWS_WITH(ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 7\n", "m"),
                        Contains("refers to vertex 7"));
    REQUIRE_THROWS_WITH(ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 2 3\n", "m"),
                        Contains("uses vertex 2 twice"));
    MeshDescription nanMesh = parseObj("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n", "m");
    nanMesh.positions[1].y = std::nan("");
    REQUIRE_THROWS_WITH(ControlMesh(nanMesh), Contains("vertex 2 has a NaN"));
    REQUIRE_THROWS_WITH(ControlMesh::fromObjText("", "empty"), Contains("no vertices or no faces"));
    REQUIRE_THROWS_AS(ControlMesh::fromObjFile("/nonexistent/mesh.obj"), FileError);
    // A fourth face on one edge (a "book" of three quads and one more on the same edge).
    REQUIRE_THROWS_WITH(ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\n"
                                                 "f 1 2 3\nf 2 1 4\nf 1 2 5\n",
                                                 "book"),
                        Contains("non-manifold"));
    // Crease tag with a vertex out of range.
    REQUIRE_THROWS_WITH(ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nt crease 2/1/0 0 9 2.0\n", "m"),
                        Contains("crease refers to vertex 9"));
}

namespace {
std::string& embedderLog() {
    static std::string log;
    return log;
}
void embedderCallback(OpenSubdiv::Far::ErrorType, const char* message) { embedderLog() += message; }
} // namespace

TEST_CASE("building meshes leaves the application's OpenSubdiv error callback installed", "[inputs]") {
    // OpenSubdiv has one process-wide error callback and no getter: an engine that installs
    // its own must still have it after dispmap built (and refused) meshes.
    embedderLog().clear();
    OpenSubdiv::Far::SetErrorCallback(&embedderCallback);
    CHECK(dmtest::shape("catmark_cube").ptexFaceCount() == 6);
    CHECK_THROWS_AS(dmtest::shape("catmark_fan"), MeshError);
    CHECK_THROWS_AS(ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 7\n", "m"), MeshError);
    OpenSubdiv::Far::Error(OpenSubdiv::Far::FAR_RUNTIME_ERROR, "probe from the test");
    OpenSubdiv::Far::SetErrorCallback(nullptr);
    CHECK(embedderLog().find("probe from the test") != std::string::npos);
}

TEST_CASE("tile sizes out of range, NaN/Inf samples and inconsistent T-junctions are rejected", "[inputs]") {
    ControlMesh cube = dmtest::shape("catmark_cube");
    REQUIRE_THROWS_WITH(uniformTileSizes(cube, 0), Contains("out of range"));
    REQUIRE_THROWS_WITH(uniformTileSizes(cube, 9), Contains("out of range"));
    auto zero = [](int, double, double) { return 0.0; };
    std::vector<int> k = uniformTileSizes(cube, 3);
    k[2] = 9;
    REQUIRE_THROWS_WITH(buildTiles(cube, k, zero), Contains("tile 2 has size 2^9"));
    REQUIRE_THROWS_WITH(buildTiles(cube, std::vector<int>(3, 3), zero), Contains("3 tile sizes given for 6"));
    REQUIRE_THROWS_WITH(buildTiles(cube, uniformTileSizes(cube, 2),
                                   [](int f, double u, double) { return f == 4 && u > 0.5 ? std::nan("") : 0.0; }),
                        Contains("at Ptex face 4"));
    REQUIRE_THROWS_AS(buildTiles(cube, uniformTileSizes(cube, 2),
                                 [](int, double, double) { return std::numeric_limits<double>::infinity(); }),
                      ArgumentError);
    ControlMesh nq = dmtest::shape("catmark_nonquads");
    REQUIRE_THROWS_WITH(uniformTileSizes(nq, 1), Contains("sub-face tiles need k >= 2"));
    // Sub-faces as large as the quads: the levels along a T-junction cannot match.
    REQUIRE_THROWS_WITH(buildTiles(nq, std::vector<int>(std::size_t(nq.ptexFaceCount()), 3), zero),
                        Contains("T-junction"));
}

TEST_CASE("a height image on a mesh without texture coordinates, or outside the image, is rejected", "[inputs]") {
    auto img = std::make_shared<HeightImage>();
    img->width = img->height = 2;
    img->values = {0.f, 0.25f, 0.5f, 1.f};
    ControlMesh cube = dmtest::shape("catmark_pole8"); // no vt lines
    REQUIRE_THROWS_WITH(imageSource(cube, img, 1.0, 0.0), Contains("no texture coordinates"));
    ControlMesh grid = ControlMesh::fromObjText("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 2 0\nvt 2 1\nvt 0 1\n"
                                                "f 1/1 2/2 3/3 4/4\n",
                                                "wide uv");
    REQUIRE_THROWS_WITH(imageSource(grid, img, 1.0, 0.0), Contains("outside the image"));
    REQUIRE_NOTHROW(imageSource(grid, img, 1.0, 0.0, true));
    REQUIRE_THROWS_WITH(imageSource(grid, img, std::nan(""), 0.0, true), Contains("finite"));
    auto empty = std::make_shared<HeightImage>();
    REQUIRE_THROWS_WITH(imageSource(grid, empty, 1.0, 0.0, true), Contains("empty"));
}

TEST_CASE("16-bit height image -> tiles: the fit interpolates the image samples", "[inputs][image]") {
    // Write a 16-bit image, read it back, map it on a grid with UVs; on a quad grid with no
    // extraordinary vertex every sample is interpolated (to double rounding).
    const dmtest::TempDir dir("dispmap_inputs_test_");
    const std::string path = dir.file("ramp.png");
    HeightImage src;
    src.width = 256;
    src.height = 128;
    for (int y = 0; y < src.height; ++y)
        for (int x = 0; x < src.width; ++x)
            src.values.push_back(float(std::round(65535.0 * (0.5 + 0.5 * std::sin(x * 0.05) * std::cos(y * 0.07))) / 65535.0));
    writeHeightPng16(path, src);
    auto img = std::make_shared<HeightImage>(readHeightPng(path));
    ControlMesh grid = ControlMesh::fromObjText(dmtest::gridObj(4, 3), "grid");
    const DisplacementFunction source = imageSource(grid, img, 0.2, -0.1);
    BuildReport rep;
    TileSet ts = buildTiles(grid, uniformTileSizes(grid, 4), source, {}, &rep);
    CHECK(rep.constrainedVertices == 0);
    // The fit stops when a sweep moves no coefficient by more than 1e-13 x (1 + max |sample|);
    // the boundary rule contracts more slowly, so the residual is left within ~1e3 of that.
    CHECK(rep.maxResidual < 1e-9);
    // The float tiles reproduce the samples to float rounding of values <= 0.1.
    double worst = 0;
    for (int f = 0; f < ts.tileCount(); ++f)
        for (int j = 0; j < 16; ++j)
            for (int i = 0; i < 16; ++i) {
                const glm::dvec2 p((i + 0.5) / 16, (j + 0.5) / 16);
                worst = std::max(worst, std::abs(ts.evaluate(f, 0, p) - source(f, p.x, p.y)));
            }
    CHECK(worst < 1e-7);
}

TEST_CASE("Spot with the brick image: a real cage, real UVs, a real height field", "[inputs][image]") {
    ControlMesh spot = dmtest::shape("spot_control_mesh");
    REQUIRE(spot.hasUVs());
    auto img = std::make_shared<HeightImage>(readHeightPng(dmtest::dataPath("skimage_brick.png")));
    CHECK(img->width == 512);
    // Spot's UV layout reaches 5 % outside [0, 1]: without wrapping that is an error.
    REQUIRE_THROWS_WITH(imageSource(spot, img, 0.05, 0.0), Contains("outside the image"));
    BuildReport rep;
    TileSet ts = buildTiles(spot, uniformTileSizes(spot, 4), imageSource(spot, img, 0.05, 0.0, true), {}, &rep);
    CHECK(ts.tileCount() == spot.ptexFaceCount());
    CHECK(rep.sweeps < 100);
    // Away from the constrained corners the samples are interpolated; the UV atlas has seams,
    // so at the constrained corners the averaged value differs by up to the data's range.
    CHECK(rep.maxResidualAwayFromConstraints < 0.05);
    for (const Tile& t : ts.tiles)
        for (float c : t.coefficients) REQUIRE(std::isfinite(c));
}

} // namespace dmtest_inputs
