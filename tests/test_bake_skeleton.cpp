// The skeleton-guided initial control mesh (bake/skeleton.h) on generated dense meshes: a
// sphere and an ellipsoid (one segment: two caps and a band; a chain: a cut in the middle), a
// torus (a ring of cuts, no caps, also with its triangles turned inward), and a T-shaped tube
// (one hinge, with equal and unequal vertex counts across its pipes). Each ICM is accepted by
// ControlMesh, closed, outward, its cut points on the dense surface and its hinge corners
// inside, with as many sides per cut as the perimeter asks. Every malformed skeleton file and
// every skeleton that cannot make a mesh is refused with a message that names the problem.
// With the outside test data, the bunny's hand-placed skeleton (examples/data/skeletons) gives
// a valid ICM.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <opensubdiv/far/primvarRefiner.h>

#include "dispmap/bake/skeleton.h"
#include "test_files.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_bake_skeleton {

using namespace dispmap;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// A dense mesh and its ray scene.
struct Target {
    DenseMesh mesh;
    std::unique_ptr<RayScene> scene;
};

using Triangles = std::vector<std::array<std::uint64_t, 3>>;

Target makeTarget(const std::string& name, std::vector<glm::dvec3> positions, const Triangles& triangles) {
    Target t{makeDenseMesh(name, std::move(positions), triangles, triangles.size()), nullptr};
    t.scene = std::make_unique<RayScene>(t.mesh.positions, t.mesh.triangles);
    return t;
}

std::uint64_t u64(int i) { return static_cast<std::uint64_t>(i); }

/// An ellipsoid with semi-axes r (x, y, z), `slices` around z and `stacks` from pole to pole,
/// triangles counter-clockwise seen from outside.
Target ellipsoid(glm::dvec3 r, int slices, int stacks) {
    std::vector<glm::dvec3> p;
    Triangles t;
    p.emplace_back(0.0, 0.0, r.z); // north pole: 0
    for (int i = 1; i < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            const double th = kPi * i / stacks, ph = 2.0 * kPi * j / slices;
            p.emplace_back(r.x * std::sin(th) * std::cos(ph), r.y * std::sin(th) * std::sin(ph), r.z * std::cos(th));
        }
    p.emplace_back(0.0, 0.0, -r.z); // south pole
    const int south = static_cast<int>(p.size()) - 1;
    const auto id = [&](int i, int j) { return u64(1 + (i - 1) * slices + (j % slices)); };
    for (int j = 0; j < slices; ++j) {
        t.push_back({0, id(1, j), id(1, j + 1)});
        t.push_back({u64(south), id(stacks - 1, j + 1), id(stacks - 1, j)});
    }
    for (int i = 1; i + 1 < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            t.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            t.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return makeTarget("ellipsoid", std::move(p), t);
}

/// A torus around z (radii R and r), counter-clockwise from outside unless `inward`.
Target torus(double R, double r, int nu, int nv, bool inward = false) {
    std::vector<glm::dvec3> p;
    Triangles t;
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            const double u = 2.0 * kPi * i / nu, v = 2.0 * kPi * j / nv;
            p.emplace_back((R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u), r * std::sin(v));
        }
    const auto id = [&](int i, int j) { return u64((i % nu) * nv + (j % nv)); };
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            std::array<std::uint64_t, 3> a{id(i, j), id(i + 1, j), id(i + 1, j + 1)}, b{id(i, j), id(i + 1, j + 1), id(i, j + 1)};
            if (inward) {
                std::swap(a[1], a[2]);
                std::swap(b[1], b[2]);
            }
            t.push_back(a);
            t.push_back(b);
        }
    return makeTarget(inward ? "torus (inward)" : "torus", std::move(p), t);
}

/// OpenSubdiv's primvar interface for positions.
struct Point {
    glm::dvec3 p{0};
    void Clear(void* = nullptr) { p = glm::dvec3(0); }
    void AddWithWeight(const Point& src, double w) { p += w * src.p; }
};

/// A smooth tube shape: the unit cubes centred at `cells` (a voxel figure), their outer faces
/// as a Catmull-Clark cage, refined `levels` times and triangulated. A limb one cube thick
/// becomes a rounded tube about 0.8 across.
Target voxelShape(const std::string& name, const std::vector<glm::ivec3>& cells, int levels) {
    const auto key = [](glm::ivec3 c) { return std::array<int, 3>{c.x, c.y, c.z}; };
    std::map<std::array<int, 3>, int> filled, corners;
    for (const glm::ivec3& c : cells) filled[key(c)] = 1;
    MeshDescription cage;
    cage.name = name + " cage";
    const auto corner = [&](glm::ivec3 g) { // g: doubled coordinates of a cube corner
        const auto [it, fresh] = corners.emplace(key(g), static_cast<int>(cage.positions.size()));
        if (fresh) cage.positions.push_back(0.5 * glm::dvec3(g));
        return it->second;
    };
    for (const glm::ivec3& c : cells)
        for (int axis = 0; axis < 3; ++axis)
            for (int sign = -1; sign <= 1; sign += 2) {
                glm::ivec3 nb = c;
                nb[axis] += sign;
                if (filled.count(key(nb))) continue;
                const int u = (axis + 1) % 3, v = (axis + 2) % 3;
                std::vector<int> ring;
                for (const auto& [su, sv] : {std::pair{-1, -1}, std::pair{1, -1}, std::pair{1, 1}, std::pair{-1, 1}}) {
                    glm::ivec3 g = 2 * c;
                    g[axis] += sign;
                    g[u] += su;
                    g[v] += sv;
                    ring.push_back(corner(g));
                }
                if (sign < 0) std::reverse(ring.begin(), ring.end());
                cage.faceSizes.push_back(4);
                cage.faceVertices.insert(cage.faceVertices.end(), ring.begin(), ring.end());
            }
    const ControlMesh mesh(cage);
    std::unique_ptr<Far::TopologyRefiner> r = mesh.createRefiner();
    r->RefineUniform(Far::TopologyRefiner::UniformOptions(levels));
    std::vector<Point> pts(static_cast<std::size_t>(r->GetNumVerticesTotal()));
    for (std::size_t i = 0; i < cage.positions.size(); ++i) pts[i].p = cage.positions[i];
    Far::PrimvarRefinerReal<double> primvar(*r);
    Point* src = pts.data();
    for (int l = 1; l <= levels; ++l) {
        Point* dst = src + r->GetLevel(l - 1).GetNumVertices();
        primvar.Interpolate(l, src, dst);
        src = dst;
    }
    const Far::TopologyLevel& last = r->GetLevel(levels);
    std::vector<glm::dvec3> p;
    for (int v = 0; v < last.GetNumVertices(); ++v) p.push_back(src[v].p);
    Triangles t;
    for (int f = 0; f < last.GetNumFaces(); ++f) {
        const auto fv = last.GetFaceVertices(f); // quads after one step
        t.push_back({u64(fv[0]), u64(fv[1]), u64(fv[2])});
        t.push_back({u64(fv[0]), u64(fv[2]), u64(fv[3])});
    }
    return makeTarget(name, std::move(p), t);
}

/// A T of tubes: arms along -x, +x (cells x = -3..3) and +y (y = 1..3), about 21k triangles.
Target tShape() {
    std::vector<glm::ivec3> cells;
    for (int x = -3; x <= 3; ++x) cells.emplace_back(x, 0, 0);
    for (int y = 1; y <= 3; ++y) cells.emplace_back(0, y, 0);
    return voxelShape("T", cells, 4);
}

Skeleton skeleton(std::vector<glm::dvec3> joints, std::vector<std::array<int, 2>> segments) {
    return Skeleton{"test.json", std::move(joints), std::move(segments)};
}

/// Whether p is inside the dense mesh: the nearest crossing along each axis direction is left
/// through a triangle facing along the ray (the mesh's stored orientation given by `orient`).
bool inside(const Target& t, const glm::dvec3& p, double orient) {
    for (int axis = 0; axis < 3; ++axis)
        for (float sign : {-1.0f, 1.0f}) {
            glm::vec3 d(0.0f);
            d[axis] = sign;
            const RayScene::Hit h = t.scene->intersect(glm::vec3(p), d, 0.0f, std::numeric_limits<float>::infinity());
            if (!h.hit || !(orient * static_cast<double>(glm::dot(h.normal, d)) > 0.0)) return false;
        }
    return true;
}

struct IcmFacts {
    int faces = 0, quads = 0, triangles = 0, vertices = 0, edges = 0;
    int onSurface = 0, insideOnly = 0; ///< vertices on the dense surface; the others, inside it
    double volume = 0.0;
};

/// Checks what every ICM must be: accepted by ControlMesh, closed (each directed edge once and
/// its reverse once: manifold and consistently oriented), oriented as the dense mesh (positive
/// volume for an outward one, `orient` 1; negative for an inward one, -1), its
/// vertices on the dense surface (cut points) or inside it (hinge corners).
IcmFacts checkIcm(const MeshDescription& d, const Target& t, double orient = 1.0) {
    IcmFacts f;
    REQUIRE_NOTHROW(ControlMesh(d));
    f.faces = static_cast<int>(d.faceSizes.size());
    f.vertices = static_cast<int>(d.positions.size());
    std::map<std::pair<int, int>, int> directed;
    for (std::size_t i = 0, o = 0; i < d.faceSizes.size(); o += static_cast<std::size_t>(d.faceSizes[i]), ++i) {
        const std::size_t n = static_cast<std::size_t>(d.faceSizes[i]);
        f.quads += n == 4;
        f.triangles += n == 3;
        const glm::dvec3 p0 = d.positions[static_cast<std::size_t>(d.faceVertices[o])];
        for (std::size_t k = 0; k < n; ++k) {
            ++directed[{d.faceVertices[o + k], d.faceVertices[o + (k + 1) % n]}];
            if (k >= 1 && k + 1 < n)
                f.volume += glm::dot(p0, glm::cross(d.positions[static_cast<std::size_t>(d.faceVertices[o + k])],
                                                    d.positions[static_cast<std::size_t>(d.faceVertices[o + k + 1])])) /
                            6.0;
        }
    }
    for (const auto& [e, count] : directed) {
        INFO("edge " << e.first << " -> " << e.second);
        REQUIRE(count == 1);
        const auto back = directed.find({e.second, e.first});
        REQUIRE(back != directed.end());
    }
    f.edges = static_cast<int>(directed.size() / 2);
    CHECK(orient * f.volume > 0.0);
    const double tol = 1e-5 * t.mesh.diagonal();
    for (const glm::dvec3& p : d.positions) {
        const RayScene::Closest c = t.scene->closest(glm::vec3(p));
        REQUIRE(c.found);
        if (static_cast<double>(c.distance) < tol)
            ++f.onSurface;
        else {
            INFO("vertex " << p.x << " " << p.y << " " << p.z << " is " << c.distance << " from the surface");
            CHECK(inside(t, p, orient));
            ++f.insideOnly;
        }
    }
    return f;
}

/// The sides a cut of the given perimeter gets with the default options.
int expectedSides(double perimeter, double diagonal) {
    const SkeletonOptions o;
    return static_cast<int>(std::clamp<long>(std::lround(o.sidesPerDiagonal * perimeter / diagonal), o.minSides, o.maxSides));
}

int sum(const std::vector<int>& v) {
    int s = 0;
    for (int x : v) s += x;
    return s;
}

} // namespace

TEST_CASE("skeleton files are parsed, comments allowed", "[bake][skeleton]") {
    const Skeleton s = parseSkeleton(R"(// two joints
        {
          "joints": [[0, 0, -0.5], /* the other end */ [0, 0, 0.5e0]],
          "segments": [[0, 1]]
        })",
                                     "two.json");
    CHECK(s.name == "two.json");
    REQUIRE(s.joints.size() == 2);
    CHECK(s.joints[1] == glm::dvec3(0.0, 0.0, 0.5));
    REQUIRE(s.segments.size() == 1);
    CHECK(s.segments[0] == std::array<int, 2>{0, 1});

    dmtest::TempDir dir("dispmap_skeleton_");
    const std::string path = dir.file("s.json");
    {
        std::ofstream f(path);
        f << R"({"segments": [[1, 2], [0, 1]], "joints": [[0,0,0], [1,0,0], [2,0,0]]})";
    }
    const Skeleton r = readSkeleton(path);
    CHECK(r.name == path);
    CHECK(r.joints.size() == 3);
    CHECK(r.segments.size() == 2);
    REQUIRE_THROWS_WITH(readSkeleton(dir.file("missing.json")), Catch::Contains("cannot open skeleton file"));
    REQUIRE_THROWS_WITH(readSkeleton(dir.path.string()), Catch::Contains("not a regular file"));

    // The examples' bunny skeleton parses wherever the checkout is.
    const Skeleton bunny = readSkeleton(std::string(DISPMAP_TEST_DATA) + "/../../examples/data/skeletons/cgal_bunny00.json");
    CHECK(bunny.joints.size() >= 10);
}

TEST_CASE("malformed skeletons are refused with a message", "[bake][skeleton]") {
    const auto parse = [](const std::string& text) { return parseSkeleton(text, "bad.json"); };
    const std::string two = R"("joints": [[0,0,0], [1,0,0]])";
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0,0]], "segments": [[0, 1])"),
                        Catch::Contains("skeleton bad.json: invalid JSON"));
    REQUIRE_THROWS_WITH(parse("[1, 2]"), Catch::Contains("not a JSON object"));
    REQUIRE_THROWS_WITH(parse(std::string(100000, '[')), Catch::Contains("nest deeper than 16"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": [], "segments": [], "joint": []})"), Catch::Contains("unknown key 'joint'"));
    REQUIRE_THROWS_WITH(parse(R"({"segments": []})"), Catch::Contains("'joints' is missing"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": []})"), Catch::Contains("'segments' is missing"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0]], "segments": []})"), Catch::Contains("joint 0 is not [x, y, z]"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0,"1"]], "segments": []})"), Catch::Contains("joint 0 is not [x, y, z]"));
    REQUIRE_THROWS_WITH(parse("{" + two + R"(, "segments": [[0, 1.5]]})"), Catch::Contains("segment 0 is not [a, b]"));
    REQUIRE_THROWS_WITH(parse("{" + two + R"(, "segments": [[0, 99999999999]]})"),
                        Catch::Contains("segment 0 refers to joint 99999999999, out of range"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0,1e999]], "segments": []})"), Catch::Contains("invalid JSON"));
    // Empty, and a lone joint.
    REQUIRE_THROWS_WITH(parse(R"({"joints": [], "segments": []})"), Catch::Contains("skeleton bad.json: has no joints"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0,0]], "segments": []})"), Catch::Contains("one joint and no segment"));
    REQUIRE_THROWS_WITH(parse("{" + two + R"(, "segments": []})"), Catch::Contains("has no segments"));
    // Indices, self segments, repeats, zero length.
    REQUIRE_THROWS_WITH(parse("{" + two + R"(, "segments": [[0, 2]]})"),
                        Catch::Contains("segment 0 [0, 2] refers to joint 2, but the 2 joints are numbered 0 to 1"));
    REQUIRE_THROWS_WITH(parse("{" + two + R"(, "segments": [[-1, 1]]})"), Catch::Contains("refers to joint -1"));
    REQUIRE_THROWS_WITH(parse("{" + two + R"(, "segments": [[0, 1], [1, 1]]})"),
                        Catch::Contains("segment 1 [1, 1] joins joint 1 to itself"));
    REQUIRE_THROWS_WITH(parse("{" + two + R"(, "segments": [[0, 1], [1, 0]]})"),
                        Catch::Contains("segment 1 [1, 0] repeats segment 0 [0, 1]"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0,0], [0,0,0]], "segments": [[0, 1]]})"),
                        Catch::Contains("segment 0 [0, 1] has zero length: joints 0 and 1 are both at (0, 0, 0)"));
    // Unused joints, two pieces, a joint of 7 segments.
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0,0], [1,0,0], [2,0,0]], "segments": [[0, 1]]})"),
                        Catch::Contains("joint 2 (2, 0, 0) is not used by any segment"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0,0], [1,0,0], [5,0,0], [6,0,0]], "segments": [[0, 1], [2, 3]]})"),
                        Catch::Contains("is not connected: joint 2 (5, 0, 0) cannot be reached from joint 0"));
    REQUIRE_THROWS_WITH(parse(R"({"joints": [[0,0,0], [1,0,0], [-1,0,0], [0,1,0], [0,-1,0], [0,0,1], [0,0,-1], [1,1,1]],
                                  "segments": [[0,1], [0,2], [0,3], [0,4], [0,5], [0,6], [0,7]]})"),
                        Catch::Contains("joint 0 (0, 0, 0) joins 7 segments; its hinge is a box of 6 faces"));
}

TEST_CASE("skeletons that cannot make a mesh of the dense one are refused", "[bake][skeleton]") {
    const Target sphere = ellipsoid(glm::dvec3(1.0), 96, 48);
    const RayScene& rs = *sphere.scene;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    // Built in code, so the NaN reaches the mesh builder (JSON has no NaN).
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, skeleton({{0, 0, -0.5}, {0, nan, 0.5}}, {{0, 1}})),
                        Catch::Contains("skeleton test.json: joint 1 has coordinate nan, not a finite number"));
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, skeleton({}, {})), Catch::Contains("has no joints"));
    // A joint outside the mesh.
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, skeleton({{0, 0, -0.5}, {0, 0, 1.5}}, {{0, 1}})),
                        Catch::Contains("skeleton test.json: joint 1 (0, 0, 1.5) is not inside the mesh"));
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs,
                                            skeleton({{0, 0, 0}, {0, 0, 0.5}, {0.5, 0, 0}, {0, -3, 0}}, {{0, 1}, {0, 2}, {0, 3}})),
                        Catch::Contains("joint 3 (0, -3, 0) is not inside the mesh"));
    // Two ends whose cuts cross: a sharp bend close to the middle of the sphere.
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, skeleton({{0, 0, -0.6}, {0, 0, 0}, {0.3, 0, 0.1}}, {{0, 1}, {1, 2}})),
                        Catch::Contains("cross each other inside the mesh"));
    // Segments folding back at a valence-2 joint.
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, skeleton({{0, 0, -0.5}, {0, 0, 0.3}, {0.05, 0, -0.4}}, {{0, 1}, {1, 2}})),
                        Catch::Contains("fold back onto each other"));
    // Three segments a box cannot separate: two of them 5 degrees apart, the third across.
    const double c5 = 0.5 * std::cos(5.0 * kPi / 180.0), s5 = 0.5 * std::sin(5.0 * kPi / 180.0);
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs,
                                            skeleton({{0, 0, 0}, {0.5, 0, 0}, {c5, s5, 0}, {0, 0.5, 0}}, {{0, 1}, {0, 2}, {0, 3}})),
                        Catch::Contains("no orientation of the hinge box at joint 0 (0, 0, 0) gives each of its 3 segments a face "
                                        "of its own (segment 0 [0, 1] and segment 1 [0, 2] leave it 5 degrees apart)"));
    // A segment far shorter than the mesh (its direction would be noise).
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, skeleton({{0, 0, 0}, {0, 0, 1e-9}}, {{0, 1}})),
                        Catch::Contains("segment 0 [0, 1] is 1e-09 long, less than a millionth of the mesh's size"));
    // Options out of range.
    const Skeleton ok = skeleton({{0, 0, -0.5}, {0, 0, 0.5}}, {{0, 1}});
    SkeletonOptions o;
    o.minSides = 2;
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, ok, o), Catch::Contains("3 <= minSides <= maxSides <= 64"));
    o = {};
    o.sidesPerDiagonal = nan;
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, ok, o), Catch::Contains("option sidesPerDiagonal nan"));
    o = {};
    o.hingeScale = 0.0;
    REQUIRE_THROWS_WITH(skeletonControlMesh(sphere.mesh, rs, ok, o), Catch::Contains("option hingeScale 0"));
}

TEST_CASE("a sphere's skeleton of one segment gives two caps and a band", "[bake][skeleton]") {
    const Target sphere = ellipsoid(glm::dvec3(1.0), 160, 80); // 25k triangles
    SkeletonReport rep;
    const MeshDescription d =
        skeletonControlMesh(sphere.mesh, *sphere.scene, skeleton({{0, 0, -0.5}, {0, 0, 0.5}}, {{0, 1}}), {}, &rep);
    CHECK(d.name == "test.json (skeleton ICM)");
    CHECK(rep.cuts == 2);
    CHECK(rep.caps == 2);
    CHECK(rep.hinges == 0);
    // The cross-section at z = +-0.5 is a circle of radius sqrt(0.75): 5.44 around, against a
    // diagonal of 2 sqrt(3): 8 * 5.44 / 3.46 = 12.6, so 13 sides.
    const int n = expectedSides(2.0 * kPi * std::sqrt(0.75), sphere.mesh.diagonal());
    CHECK(n == 13);
    CHECK(rep.cutSides == std::vector<int>{n, n});
    const IcmFacts f = checkIcm(d, sphere);
    CHECK(f.faces == 2 + n);
    CHECK(f.quads == n);
    CHECK(f.vertices == 2 * n);
    CHECK(f.onSurface == 2 * n);
    CHECK(f.vertices - f.edges + f.faces == 2);
}

TEST_CASE("a chain of joints puts a cut at each inner joint", "[bake][skeleton]") {
    // An ellipsoid 4 long and 1 across: the middle cross-section is twice as long around as the
    // ones near the ends, so the cuts get different numbers of sides and the bands triangles.
    const Target cigar = ellipsoid(glm::dvec3(0.5, 0.5, 2.0), 128, 128);
    SkeletonReport rep;
    const MeshDescription d = skeletonControlMesh(
        cigar.mesh, *cigar.scene, skeleton({{0, 0, -1.8}, {0, 0, 0}, {0.05, 0, 1.2}, {0.1, 0, 1.8}}, {{0, 1}, {1, 2}, {2, 3}}),
        {}, &rep);
    CHECK(rep.cuts == 4);
    CHECK(rep.caps == 2);
    CHECK(rep.hinges == 0);
    REQUIRE(rep.cutSides.size() == 4);
    CHECK(rep.cutSides[1] == expectedSides(2.0 * kPi * 0.5, cigar.mesh.diagonal()));
    CHECK(rep.cutSides[0] < rep.cutSides[1]);
    const IcmFacts f = checkIcm(d, cigar);
    CHECK(f.triangles > 0);
    CHECK(f.onSurface == sum(rep.cutSides));
    CHECK(f.vertices - f.edges + f.faces == 2);
}

TEST_CASE("a torus ring of joints gives cuts and bands only", "[bake][skeleton]") {
    // R = 2, r = 0.8: a meridian section is 5.03 around, the diagonal sqrt(5.6^2 * 2 + 1.6^2) =
    // 8.08, so 8 * 5.03 / 8.08 = 4.98 and 5 sides.
    std::vector<glm::dvec3> joints;
    std::vector<std::array<int, 2>> segments;
    const int nj = 6;
    for (int i = 0; i < nj; ++i) {
        const double a = 2.0 * kPi * i / nj;
        joints.emplace_back(2.0 * std::cos(a), 2.0 * std::sin(a), 0.0);
        segments.push_back({i, (i + 1) % nj});
    }
    for (bool inward : {false, true}) {
        const Target t = torus(2.0, 0.8, 160, 64, inward); // 20k triangles
        INFO(t.mesh.name);
        SkeletonReport rep;
        const MeshDescription d = skeletonControlMesh(t.mesh, *t.scene, skeleton(joints, segments), {}, &rep);
        CHECK(rep.cuts == nj);
        CHECK(rep.caps == 0);
        CHECK(rep.hinges == 0);
        const int n = expectedSides(2.0 * kPi * 0.8, t.mesh.diagonal());
        CHECK(n == 5);
        CHECK(rep.cutSides == std::vector<int>(nj, n));
        const IcmFacts f = checkIcm(d, t, inward ? -1.0 : 1.0);
        CHECK(f.faces == nj * n);
        CHECK(f.quads == nj * n);
        CHECK(f.onSurface == nj * n);
        CHECK(f.vertices - f.edges + f.faces == 0); // genus 1
    }
}

TEST_CASE("a T-shaped tube gets one hinge", "[bake][skeleton]") {
    const Target t = tShape();
    // The hinge in the middle, a cut on each side arm half-way, and the three ends.
    const Skeleton s = skeleton({{0, 0, 0}, {-1.5, 0, 0}, {-2.6, 0, 0}, {1.5, 0, 0}, {2.6, 0, 0}, {0, 2.6, 0}},
                                {{0, 1}, {1, 2}, {0, 3}, {3, 4}, {0, 5}});
    SECTION("cuts of four sides: quads throughout") {
        SkeletonReport rep;
        const MeshDescription d = skeletonControlMesh(t.mesh, *t.scene, s, {}, &rep);
        CHECK(rep.hinges == 1);
        CHECK(rep.cuts == 5);
        CHECK(rep.caps == 3);
        CHECK(rep.cutSides == std::vector<int>(5, 4)); // thin arms: the minimum
        const IcmFacts f = checkIcm(d, t);
        CHECK(f.insideOnly == 8); // the box's corners
        CHECK(f.onSurface == 20);
        CHECK(f.faces == 3 /* caps */ + 3 /* free box faces */ + 5 * 4 /* bands */);
        CHECK(f.quads == f.faces);
        CHECK(f.vertices - f.edges + f.faces == 2);
    }
    SECTION("cuts of more sides than a box face: triangles where the pipes meet it") {
        SkeletonOptions o;
        o.sidesPerDiagonal = 20.0;
        SkeletonReport rep;
        const MeshDescription d = skeletonControlMesh(t.mesh, *t.scene, s, o, &rep);
        CHECK(rep.hinges == 1);
        for (int n : rep.cutSides) CHECK(n > 4);
        const IcmFacts f = checkIcm(d, t);
        CHECK(f.insideOnly == 8);
        CHECK(f.onSurface == sum(rep.cutSides));
        CHECK(f.triangles > 0);
        CHECK(f.vertices - f.edges + f.faces == 2);
    }
    SECTION("a hinge next to the arms' ends, and a smaller box") {
        SkeletonOptions o;
        o.hingeScale = 0.3;
        SkeletonReport rep;
        const MeshDescription d = skeletonControlMesh(
            t.mesh, *t.scene, skeleton({{0, 0, 0}, {-2.6, 0, 0}, {2.6, 0, 0}, {0, 2.6, 0}}, {{0, 1}, {0, 2}, {3, 0}}), o, &rep);
        CHECK(rep.hinges == 1);
        CHECK(rep.caps == 3);
        const IcmFacts f = checkIcm(d, t);
        CHECK(f.insideOnly == 8);
    }
}

TEST_CASE("a cross of tubes gets a hinge of four pipes", "[bake][skeleton]") {
    std::vector<glm::ivec3> cells;
    for (int x = -3; x <= 3; ++x) cells.emplace_back(x, 0, 0);
    for (int y = -3; y <= 3; ++y)
        if (y != 0) cells.emplace_back(0, y, 0);
    const Target t = voxelShape("cross", cells, 4);
    SkeletonReport rep;
    const MeshDescription d = skeletonControlMesh(
        t.mesh, *t.scene, skeleton({{0, 0, 0}, {-2.6, 0, 0}, {2.6, 0, 0}, {0, -2.6, 0}, {0, 2.6, 0}}, {{0, 1}, {0, 2}, {0, 3}, {0, 4}}),
        {}, &rep);
    CHECK(rep.hinges == 1);
    CHECK(rep.cuts == 4);
    CHECK(rep.caps == 4);
    const IcmFacts f = checkIcm(d, t);
    CHECK(f.faces == 4 /* caps */ + 2 /* box faces along z */ + 4 * 4 /* bands */);
    CHECK(f.insideOnly == 8);
    CHECK(f.vertices - f.edges + f.faces == 2);
}

#ifdef DISPMAP_SHARED_TESTDATA
TEST_CASE("the bunnies' hand-placed skeletons give valid control meshes", "[bake][skeleton]") {
    for (const char* stem : {"cgal_bunny00", "bunny_npm_lowres"}) {
        INFO(stem);
        const std::string ext = std::string(stem) == "cgal_bunny00" ? ".off" : ".obj";
        DenseMesh bunny = readDenseMesh(std::string(DISPMAP_SHARED_TESTDATA) + "/dense-meshes/" + stem + ext);
        Target t{std::move(bunny), nullptr};
        t.scene = std::make_unique<RayScene>(t.mesh.positions, t.mesh.triangles);
        const Skeleton s =
            readSkeleton(std::string(DISPMAP_TEST_DATA) + "/../../examples/data/skeletons/" + stem + ".json");
        SkeletonReport rep;
        const MeshDescription d = skeletonControlMesh(t.mesh, *t.scene, s, {}, &rep);
        // 12 joints: a spine of four, the head (a hinge of four segments), the nose, two ears of three.
        CHECK(rep.hinges == 1);
        CHECK(rep.cuts == 11);
        CHECK(rep.caps == 4); // the rump, the nose, the ears' tips
        const IcmFacts f = checkIcm(d, t);
        CHECK(f.onSurface == sum(rep.cutSides));
        CHECK(f.insideOnly == 8);
        CHECK(f.vertices - f.edges + f.faces == 2);
    }
}
#endif

} // namespace dmtest_bake_skeleton
