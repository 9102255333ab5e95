#pragma once
// Non-height-field mesostructure (Mehra & Kumar §3.1, "non height-field"; Donnelly §8.3,
// "chain mail could be rendered in this manner"): a closed triangle mesh (beads, rings,
// overhangs) standing on the slab's floor, in the voxel space of kernels/meso.h (x and y
// periodic, the solid also filling z < 0).
//
// The mesh is voxelised into S^3 sub-voxels per voxel: a sub-voxel is solid when its centre is
// inside the mesh (parity of the crossings of a vertical line) or a triangle may pass through
// it (its plane passes within the sub-voxel's half diagonal and its bounding box meets it: a
// superset of the true overlaps, so the bounds below stay bounds). From that:
//  * buildSolidDistanceMap: Donnelly's signed map, FH's exact transform in 3D over the
//    sub-voxel centres (approximate for the mesh: half a sub-voxel of offset and the
//    voxelisation; as in the chapter, no bound);
//  * buildSolidDdm: the conservative DDM over the solid sub-voxel boxes and the floor (the
//    same box bound and cone test as the height-field builder), searched in shells of voxels;
//  * the triangle lists: each voxel lists the copies of the triangles that may cross it
//    (MesoSolidEntry: the triangle and the tile of the copy next to that voxel, so a marcher
//    never searches the periodic shifts), as entryStart / entries; packSolid gives the GPU's
//    lists (a word an entry) and triangles (with the corners' normals);
//  * buildMesoSolidMaps (meso/march.h): the maps the marchers and the renderer read;
//    marchDdmSolid (meso/march.h, kern::dmMesoMarchDdmSolid on the CPU and the GPU):
//    Algorithm 3.1 where a voxel whose distance is 0 tests the ray exactly against the
//    triangles listed for it; marchSolidReference: every voxel's triangles, in double.
#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>

#include <glm/gtc/packing.hpp>

#include "dispmap/core/parallel.h"
#include "dispmap/meso/ddm.h"
#include "dispmap/meso/distance_map.h"

namespace dispmap {

/// One triangle of a solid as a voxel lists it: the copy of triangle `triangle` that passes
/// near the unwrapped voxel `voxel` (the mesh is periodic in x and y; a voxel beyond the tile
/// lists the copy shifted by whole tiles).
struct MesoSolidEntry {
    int triangle = 0;
    glm::ivec3 voxel{0};
};

struct MesoSolid {
    int width = 0, height = 0, layers = 0, sub = 2;
    std::vector<std::uint8_t> solid;           ///< [z][y][x] over the sub-voxel grid
    std::vector<std::uint8_t> voxelSolid;      ///< any solid sub-voxel, per voxel [k][j][i]
    std::vector<glm::dvec3> vertices;          ///< voxel space
    std::vector<glm::dvec3> normals;           ///< per vertex: unit, the area-weighted mean of its triangles' normals
    std::vector<std::array<int, 3>> triangles;
    /// The triangles that may cross voxel v = voxelIndex(i, j, k): entries[entryStart[v]] up to
    /// entries[entryStart[v + 1]] (one list for every voxel, in voxelIndex order).
    std::vector<std::uint32_t> entryStart;
    std::vector<MesoSolidEntry> entries;

    std::size_t voxelIndex(int i, int j, int k) const {
        return (static_cast<std::size_t>(k) * static_cast<std::size_t>(height) + static_cast<std::size_t>(detail::wrapIndex(j, height))) *
                   static_cast<std::size_t>(width) +
               static_cast<std::size_t>(detail::wrapIndex(i, width));
    }
    /// Triangle t as the marchers read it: part 0 its first corner a, 1 and 2 its edges
    /// e1 = b - a and e2 = c - a (voxel space, w = 0).
    glm::dvec4 triangleRow(std::size_t t, int part) const {
        const auto& tri = triangles[t];
        const glm::dvec3& a = vertices[static_cast<std::size_t>(tri[0])];
        if (part == 0) return glm::dvec4(a, 0.0);
        return glm::dvec4(vertices[static_cast<std::size_t>(tri[static_cast<std::size_t>(part)])] - a, 0.0);
    }
    /// Entry e as one word (packSolid): its triangle in the low 24 bits, then the tile of the
    /// voxel it was listed from (floor(voxel / size) + 8, four bits for x and four for y).
    std::uint32_t entryWord(std::size_t e) const {
        const MesoSolidEntry& en = entries[e];
        const auto tile = [](int v, int n) { return static_cast<std::uint32_t>((v >= 0 ? v / n : -((-v - 1) / n) - 1) + 8); };
        return static_cast<std::uint32_t>(en.triangle) | tile(en.voxel.x, width) << 24 | tile(en.voxel.y, height) << 28;
    }
    /// As the GPU holds the solid (packSolid): a word a voxel and an entry, three 16-byte rows a triangle.
    std::size_t bytes() const { return (entryStart.size() + entries.size()) * 4 + triangles.size() * 48; }
    bool subSolid(int x, int y, int z) const {
        if (z < 0) return true;
        if (z >= layers * sub) return false;
        const int fw = width * sub, fh = height * sub;
        return solid[(static_cast<std::size_t>(z) * static_cast<std::size_t>(fh) + static_cast<std::size_t>(detail::wrapIndex(y, fh))) *
                         static_cast<std::size_t>(fw) +
                     static_cast<std::size_t>(detail::wrapIndex(x, fw))] != 0;
    }
    double solidShare() const {
        std::size_t n = 0;
        for (std::uint8_t v : solid) n += v;
        return static_cast<double>(n) / static_cast<double>(std::max<std::size_t>(solid.size(), 1));
    }
};

/// Where a mesh lies in the tile (mesoSolidFromMesh): the mesh's point `corner` is the tile's
/// corner on the floor, voxel-space (0, 0, 0), and `size` mesh units span the tile's width
/// (voxels are cubes: the tile's height spans size * height / width). A mesh may cross the
/// tile's sides: what lies beyond one shows in the next tile (x and y repeat), so a ring that
/// crosses the side at x = size links the ring of the next tile, as chain mail does.
struct MesoSolidTile {
    glm::dvec3 corner{0.0};
    double size = 1;
};

/// Largest distance, in tiles, of a mesh's vertices from its tile's sides and below its floor
/// (mesoSolidFromMesh): a triangle is copied once per tile it spans, and an entry holds its
/// copy's tile in four bits (MesoSolid::entryWord).
inline constexpr double kMaxSolidTileReach = 4;
static_assert(kMaxSolidTileReach + 2 <= 7, "MesoSolid::entryWord holds an entry's tile, -8 .. 7, in four bits");
/// Most triangles one voxel may list: a pixel's march tests every triangle of each 0 voxel it
/// meets, so a voxel with thousands would stall the GPU (a finer grid or a coarser mesh is the cure).
inline constexpr std::size_t kMaxSolidVoxelTriangles = 1024;

namespace detail {
inline void checkSolidMesh(const std::vector<glm::dvec3>& vertices, const std::vector<std::array<int, 3>>& triangles) {
    if (triangles.empty()) throw ArgumentError("mesh mesostructure: the mesh has no triangles");
    for (const glm::dvec3& v : vertices)
        if (!std::isfinite(v.x + v.y + v.z)) throw ArgumentError("mesh mesostructure: a vertex is not finite");
    for (const auto& t : triangles)
        for (int i : t)
            if (i < 0 || static_cast<std::size_t>(i) >= vertices.size())
                throw ArgumentError("mesh mesostructure: vertex index " + std::to_string(i) + " out of range");
}
} // namespace detail

/// Voxelises a closed mesh placed by `tile` into width x height x layers voxels with sub^3
/// sub-voxels each. ArgumentError for no triangles, indices out of range, non-finite vertices
/// or tile, a mesh that rises above the layers or reaches more than kMaxSolidTileReach tiles
/// beyond its tile's sides or below its floor, more than 2^24 triangles, a voxel crossed by
/// more than kMaxSolidVoxelTriangles triangles, more than 2^31 - 1 voxels and entries.
inline MesoSolid mesoSolidFromMesh(const std::vector<glm::dvec3>& vertices, const std::vector<std::array<int, 3>>& triangles, int width,
                                   int height, int layers, const MesoSolidTile& tile, int sub = 2) {
    detail::checkMesoSize("mesh mesostructure", width, height, layers);
    if (sub < 1 || sub > 8) throw ArgumentError("mesh mesostructure: sub-voxels " + std::to_string(sub) + " not in 1..8");
    detail::checkSolidMesh(vertices, triangles);
    if (triangles.size() > std::size_t{1} << 24) throw ArgumentError("mesh mesostructure: more than 2^24 triangles");
    if (!std::isfinite(tile.corner.x + tile.corner.y + tile.corner.z) || !(tile.size > 0) || !std::isfinite(tile.size))
        throw ArgumentError("mesh mesostructure: the tile needs a finite corner and a size > 0");
    const double scale = width / tile.size;
    double top = -std::numeric_limits<double>::infinity(), beyond = 0;
    for (const glm::dvec3& v : vertices) {
        const glm::dvec3 q = (v - tile.corner) * scale;
        top = std::max(top, q.z);
        beyond = std::max({beyond, -q.x / width, q.x / width - 1, -q.y / height, q.y / height - 1, -q.z / width});
    }
    if (top > layers)
        throw ArgumentError("mesh mesostructure: the mesh is " + std::to_string(top) + " voxels tall, more than " + std::to_string(layers) +
                            " layers");
    if (!(beyond <= kMaxSolidTileReach))
        throw ArgumentError("mesh mesostructure: the mesh reaches " + std::to_string(beyond) + " tiles beyond its tile's sides or below its floor (at most " +
                            std::to_string(static_cast<int>(kMaxSolidTileReach)) + ")");
    MesoSolid s;
    s.width = width;
    s.height = height;
    s.layers = layers;
    s.sub = sub;
    s.triangles = triangles;
    for (const glm::dvec3& v : vertices) s.vertices.push_back((v - tile.corner) * scale);
    const int fw = width * sub, fh = height * sub, fz = layers * sub;
    const double h = 1.0 / sub;
    s.solid.assign(static_cast<std::size_t>(fw) * static_cast<std::size_t>(fh) * static_cast<std::size_t>(fz), 0);
    const auto mark = [&](int x, int y, int z) {
        if (z < 0 || z >= fz) return;
        s.solid[(static_cast<std::size_t>(z) * static_cast<std::size_t>(fh) + static_cast<std::size_t>(detail::wrapIndex(y, fh))) *
                    static_cast<std::size_t>(fw) +
                static_cast<std::size_t>(detail::wrapIndex(x, fw))] = 1;
    };
    // Inside: parity of the crossings of the vertical line through each sub-voxel centre, with
    // every copy of each triangle (shifted by whole tiles) that the line meets.
    std::vector<std::vector<double>> zs(static_cast<std::size_t>(fw) * static_cast<std::size_t>(fh));
    for (const auto& t : s.triangles) {
        const glm::dvec3 &a = s.vertices[static_cast<std::size_t>(t[0])], &b = s.vertices[static_cast<std::size_t>(t[1])],
                         &c = s.vertices[static_cast<std::size_t>(t[2])];
        const double d = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
        if (d == 0) continue; // vertical or degenerate: no vertical line crosses it once
        const glm::dvec3 tlo = glm::min(a, glm::min(b, c)), thi = glm::max(a, glm::max(b, c));
        // Sub-voxel columns x whose centre (x + 1/2) h may lie in [tlo.x, thi.x] (unwrapped).
        const int x0 = static_cast<int>(std::ceil(tlo.x / h - 0.5)), x1 = static_cast<int>(std::floor(thi.x / h - 0.5));
        const int y0 = static_cast<int>(std::ceil(tlo.y / h - 0.5)), y1 = static_cast<int>(std::floor(thi.y / h - 0.5));
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const double px = (x + 0.5) * h, py = (y + 0.5) * h;
                const double u = ((px - a.x) * (c.y - a.y) - (c.x - a.x) * (py - a.y)) / d;
                const double v = ((b.x - a.x) * (py - a.y) - (px - a.x) * (b.y - a.y)) / d;
                if (u < 0 || v < 0 || u + v > 1) continue;
                zs[static_cast<std::size_t>(detail::wrapIndex(y, fh)) * static_cast<std::size_t>(fw) + static_cast<std::size_t>(detail::wrapIndex(x, fw))]
                    .push_back(a.z + u * (b.z - a.z) + v * (c.z - a.z));
            }
    }
    for (int y = 0; y < fh; ++y)
        for (int x = 0; x < fw; ++x) {
            std::vector<double>& z = zs[static_cast<std::size_t>(y) * static_cast<std::size_t>(fw) + static_cast<std::size_t>(x)];
            std::sort(z.begin(), z.end());
            // A line through a shared edge or vertex meets each triangle there: one crossing.
            z.erase(std::unique(z.begin(), z.end(), [](double p, double q) { return q - p <= 1e-9; }), z.end());
            for (std::size_t k = 0; k + 1 < z.size(); k += 2)
                for (int iz = static_cast<int>(std::clamp(std::floor(z[k] / h), 0.0, double(fz))); iz < fz && (iz + 0.5) * h <= z[k + 1]; ++iz)
                    if ((iz + 0.5) * h >= z[k]) mark(x, y, iz);
        }
    // Surface: sub-voxels (and voxels) the triangle's plane passes near, inside its box.
    std::vector<std::vector<MesoSolidEntry>> lists(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
                                                   static_cast<std::size_t>(layers));
    s.normals.assign(s.vertices.size(), glm::dvec3(0));
    std::size_t entryCount = 0;
    for (std::size_t ti = 0; ti < s.triangles.size(); ++ti) {
        const auto& t = s.triangles[ti];
        const glm::dvec3 &a = s.vertices[static_cast<std::size_t>(t[0])], &b = s.vertices[static_cast<std::size_t>(t[1])],
                         &c = s.vertices[static_cast<std::size_t>(t[2])];
        glm::dvec3 n = glm::cross(b - a, c - a);
        const double nl = glm::length(n);
        if (!(nl > 0)) continue; // a degenerate triangle covers nothing
        for (int i : t) s.normals[static_cast<std::size_t>(i)] += n; // |n| is twice the area
        n /= nl;
        const glm::dvec3 tlo = glm::min(a, glm::min(b, c)), thi = glm::max(a, glm::max(b, c));
        // The cells the triangle's box meets, closed: a face on a cell wall (z = k, the top
        // z = layers, a side x = k) belongs to the cells on both sides of it. z is clamped to
        // the slab (below the floor is solid anyway) before it becomes an int.
        const auto visit = [&](double cell, const auto& fn) {
            const double cellsZ = layers / cell;
            const glm::ivec3 i0(std::ceil(tlo.x / cell) - 1, std::ceil(tlo.y / cell) - 1, std::clamp(std::ceil(tlo.z / cell) - 1, -1.0, cellsZ));
            const glm::ivec3 i1(std::floor(thi.x / cell), std::floor(thi.y / cell), std::clamp(std::floor(thi.z / cell), -1.0, cellsZ));
            const double reach = 0.5 * std::sqrt(3.0) * cell;
            for (int z = i0.z; z <= i1.z; ++z)
                for (int y = i0.y; y <= i1.y; ++y)
                    for (int x = i0.x; x <= i1.x; ++x)
                        if (std::abs(glm::dot(n, (glm::dvec3(x, y, z) + 0.5) * cell - a)) <= reach) fn(x, y, z);
        };
        visit(h, mark);
        visit(1.0, [&](int x, int y, int z) {
            if (z < 0 || z >= layers) return;
            std::vector<MesoSolidEntry>& list = lists[s.voxelIndex(x, y, z)];
            if (list.size() >= kMaxSolidVoxelTriangles)
                throw ArgumentError("mesh mesostructure: voxel (" + std::to_string(detail::wrapIndex(x, width)) + ", " +
                                    std::to_string(detail::wrapIndex(y, height)) + ", " + std::to_string(z) + ") is crossed by more than " +
                                    std::to_string(kMaxSolidVoxelTriangles) + " triangles: more voxels (size, layers) or a coarser mesh");
            if (++entryCount >= (std::size_t{1} << 31) - lists.size())
                throw ArgumentError("mesh mesostructure: more than 2^31 - 1 voxels and voxel-triangle entries");
            list.push_back({static_cast<int>(ti), glm::ivec3(x, y, z)});
        });
    }
    for (glm::dvec3& n : s.normals) {
        const double l = glm::length(n);
        n = l > 0 ? n / l : glm::dvec3(0, 0, 1); // a vertex of degenerate triangles only: never shaded
    }
    s.entryStart.reserve(lists.size() + 1);
    for (const auto& l : lists) {
        s.entryStart.push_back(static_cast<std::uint32_t>(s.entries.size()));
        s.entries.insert(s.entries.end(), l.begin(), l.end());
    }
    s.entryStart.push_back(static_cast<std::uint32_t>(s.entries.size()));
    s.voxelSolid.assign(lists.size(), 0);
    for (int z = 0; z < fz; ++z)
        for (int y = 0; y < fh; ++y)
            for (int x = 0; x < fw; ++x)
                if (s.subSolid(x, y, z)) s.voxelSolid[s.voxelIndex(x / sub, y / sub, z / sub)] = 1;
    return s;
}

/// Voxelises a closed mesh fitted to the tile: x and y of its vertices' bounding box scaled
/// uniformly onto the tile (the larger extent fills it), z by the same scale from its lowest
/// point at z = `floorGap` voxels up (mesoSolidFromMesh with that MesoSolidTile).
/// ArgumentError as that, and for a flat (zero-extent) bounding box.
inline MesoSolid mesoSolidFromMesh(const std::vector<glm::dvec3>& vertices, const std::vector<std::array<int, 3>>& triangles, int width,
                                   int height, int layers, int sub = 2, double floorGap = 0.0) {
    detail::checkMesoSize("mesh mesostructure", width, height, layers);
    detail::checkSolidMesh(vertices, triangles);
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const glm::dvec3& v : vertices) {
        lo = glm::min(lo, v);
        hi = glm::max(hi, v);
    }
    const glm::dvec3 ext = hi - lo;
    if (!(ext.x > 0 && ext.y > 0 && ext.z > 0)) throw ArgumentError("mesh mesostructure: the mesh is flat (degenerate bounding box)");
    const double scale = std::min(width / ext.x, height / ext.y);
    return mesoSolidFromMesh(vertices, triangles, width, height, layers, MesoSolidTile{lo - glm::dvec3(0, 0, floorGap / scale), width / scale}, sub);
}

/// The octahedral encoding of unit vector n in [-1, 1]^2 (the inverse of kern::dmOctDecode).
inline glm::dvec2 octEncode(const glm::dvec3& n) {
    const double l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
    glm::dvec2 e(n.x / l1, n.y / l1);
    if (n.z < 0) e = glm::dvec2((1.0 - std::abs(e.y)) * (e.x >= 0 ? 1.0 : -1.0), (1.0 - std::abs(e.x)) * (e.y >= 0 ? 1.0 : -1.0));
    return e;
}

/// The solid as the GPU reads it (shaders/meso/march.glsl, bindings DM_MESO_SOLID_BINDING and
/// one more): `lists`, the entry range of every voxel (entryStart, offset by its own length so
/// that a range indexes `lists` itself) followed by the entries (MesoSolid::entryWord);
/// `triangles`, three rows a triangle, xyz the float bits of triangleRow(t, part) and w the
/// unit normal of the triangle's corner `part` (glm::packSnorm2x16 of octEncode).
struct PackedSolid {
    std::vector<std::uint32_t> lists;
    std::vector<glm::uvec4> triangles;
};
inline PackedSolid packSolid(const MesoSolid& s) {
    if (s.normals.size() != s.vertices.size() || s.entryStart.empty() || s.entryStart.back() != s.entries.size())
        throw ArgumentError("packSolid: the solid's normals or lists are missing (build it with mesoSolidFromMesh)");
    PackedSolid p;
    const auto offset = static_cast<std::uint32_t>(s.entryStart.size());
    p.lists.reserve(s.entryStart.size() + s.entries.size());
    for (std::uint32_t v : s.entryStart) p.lists.push_back(v + offset);
    for (std::size_t e = 0; e < s.entries.size(); ++e) p.lists.push_back(s.entryWord(e));
    p.triangles.reserve(3 * s.triangles.size());
    for (std::size_t t = 0; t < s.triangles.size(); ++t)
        for (int part = 0; part < 3; ++part) {
            const glm::vec3 r(s.triangleRow(t, part));
            const glm::vec2 n(octEncode(s.normals[static_cast<std::size_t>(s.triangles[t][static_cast<std::size_t>(part)])]));
            p.triangles.emplace_back(glm::floatBitsToUint(r.x), glm::floatBitsToUint(r.y), glm::floatBitsToUint(r.z), glm::packSnorm2x16(n));
        }
    return p;
}

/// Appends a closed UV sphere (outward triangles, n rings) of radius r at c: a bead.
inline void appendUvSphere(glm::dvec3 c, double r, int n, std::vector<glm::dvec3>& v, std::vector<std::array<int, 3>>& t) {
    const int base = static_cast<int>(v.size());
    v.push_back(c + glm::dvec3(0, 0, -r));
    for (int i = 1; i < n; ++i)
        for (int j = 0; j < 2 * n; ++j) {
            const double th = 3.14159265358979323846 * i / n, ph = 3.14159265358979323846 * j / n;
            v.push_back(c + r * glm::dvec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), -std::cos(th)));
        }
    v.push_back(c + glm::dvec3(0, 0, r));
    const int top = static_cast<int>(v.size()) - 1;
    const auto id = [&](int i, int j) { return base + 1 + (i - 1) * 2 * n + (j % (2 * n)); };
    for (int j = 0; j < 2 * n; ++j) t.push_back({base, id(1, j + 1), id(1, j)});
    for (int i = 1; i + 1 < n; ++i)
        for (int j = 0; j < 2 * n; ++j) {
            t.push_back({id(i, j), id(i, j + 1), id(i + 1, j + 1)});
            t.push_back({id(i, j), id(i + 1, j + 1), id(i + 1, j)});
        }
    for (int j = 0; j < 2 * n; ++j) t.push_back({id(n - 1, j), id(n - 1, j + 1), top});
}

/// Appends a closed torus (outward triangles, n segments around its axis, m around its tube)
/// centred at c with unit axis `axis`, radii R (of the centre circle) > r (of the tube): a
/// ring of chain mail.
inline void appendTorus(glm::dvec3 c, glm::dvec3 axis, double R, double r, int n, int m, std::vector<glm::dvec3>& v,
                        std::vector<std::array<int, 3>>& t) {
    const glm::dvec3 w = glm::normalize(axis);
    const glm::dvec3 u = glm::normalize(glm::cross(w, std::abs(w.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0))), b = glm::cross(w, u);
    const int base = static_cast<int>(v.size());
    const double pi = 3.14159265358979323846;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) {
            const double a = 2 * pi * i / n, e = 2 * pi * j / m;
            const glm::dvec3 radial = std::cos(a) * u + std::sin(a) * b;
            v.push_back(c + (R + r * std::cos(e)) * radial + r * std::sin(e) * w);
        }
    const auto id = [&](int i, int j) { return base + (i % n) * m + (j % m); };
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) {
            t.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            t.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
}

/// Donnelly's signed map of the solid: the samples at (i, j, k + 1/2) read the exact distance
/// between the sub-voxel centre next to them and the nearest solid (outside) or empty (inside,
/// negative) sub-voxel centre, the floor z < 0 being solid.
inline DistanceMap buildSolidDistanceMap(const MesoSolid& s) {
    detail::checkMesoSize("solid distance map", s.width, s.height, s.layers);
    const int S = s.sub, fw = s.width * S, fh = s.height * S, fz = s.layers * S;
    const std::size_t n = static_cast<std::size_t>(fw) * static_cast<std::size_t>(fh) * static_cast<std::size_t>(fz);
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> out(n), in(n);
    for (std::size_t i = 0; i < n; ++i) {
        out[i] = s.solid[i] ? 0.0 : inf;
        in[i] = s.solid[i] ? inf : 0.0;
    }
    const auto transform = [&](std::vector<double>& g, bool floorSolid) {
        for (int z = 0; z < fz; ++z) squaredDistanceTransform2D(g.data() + static_cast<std::ptrdiff_t>(z) * fw * fh, fw, fh);
        // z is not periodic: one line per column, with the floor as a feature below z = 0.
        const std::size_t zn = static_cast<std::size_t>(std::max(fz, 1)) + 1; // fz >= 2 (checked): the max tells GCC
        std::vector<double> f(zn), d(zn), zz(zn + 1);
        std::vector<int> v(zn);
        for (int y = 0; y < fh; ++y)
            for (int x = 0; x < fw; ++x) {
                f[0] = floorSolid ? 0.0 : inf;
                for (int z = 0; z < fz; ++z) f[static_cast<std::size_t>(z) + 1] = g[(static_cast<std::size_t>(z) * static_cast<std::size_t>(fh) + static_cast<std::size_t>(y)) * static_cast<std::size_t>(fw) + static_cast<std::size_t>(x)];
                distanceTransform1D(f.data(), fz + 1, 1.0, d.data(), v.data(), zz.data());
                for (int z = 0; z < fz; ++z) g[(static_cast<std::size_t>(z) * static_cast<std::size_t>(fh) + static_cast<std::size_t>(y)) * static_cast<std::size_t>(fw) + static_cast<std::size_t>(x)] = d[static_cast<std::size_t>(z) + 1];
            }
    };
    transform(out, true);
    transform(in, false);
    DistanceMap m;
    m.width = s.width;
    m.height = s.height;
    m.layers = s.layers;
    m.subsamples = S;
    m.d.resize(static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height) * static_cast<std::size_t>(s.layers));
    for (int k = 0; k < s.layers; ++k)
        for (int j = 0; j < s.height; ++j)
            for (int i = 0; i < s.width; ++i) {
                const std::size_t at = (static_cast<std::size_t>(k * S + S / 2) * static_cast<std::size_t>(fh) + static_cast<std::size_t>(j * S)) *
                                           static_cast<std::size_t>(fw) +
                                       static_cast<std::size_t>(i * S);
                m.d[s.voxelIndex(i, j, k)] = static_cast<float>(out[at] > 0 ? std::sqrt(out[at]) / S : -std::sqrt(in[at]) / S);
            }
    return m;
}

/// The conservative DDM of the solid (see the top of this file). Cap default: `layers`. Rows of
/// voxels on `threads` threads (core/parallel.h; the same map for every count).
inline DirectionalDistanceMap buildSolidDdm(const MesoSolid& s, const ConeSet& cones, float cap = 0, int threads = 0) {
    cones.validate();
    checkThreads(threads, "directional distance map");
    if (!(cap >= 0) || !(cap <= kMaxDdmCap))
        throw ArgumentError("directional distance map: cap " + std::to_string(cap) + " not in [0, " + std::to_string(static_cast<int>(kMaxDdmCap)) + "]");
    DirectionalDistanceMap m;
    m.width = s.width;
    m.height = s.height;
    m.layers = s.layers;
    m.cones = cones;
    m.cap = cap > 0 ? cap : static_cast<float>(s.layers);
    m.d.assign(static_cast<std::size_t>(cones.count()) * s.voxelSolid.size(), m.cap);
    const int S = s.sub;
    const double h = 1.0 / S, bottom = -4.0 * s.layers - 1.0;
    std::vector<detail::ConeTest> tests;
    for (int c = 0; c < cones.count(); ++c) tests.push_back(detail::coneTest(cones, c));
    const int C = cones.count();
    // One row of voxels (layer, row) a task: each voxel is independent. All cones of a voxel
    // share one search (as buildDdm): every box's distance once, tested against the cones it
    // could still improve; the shells go on while any cone's best may improve.
    detail::parallelRows(s.layers * s.height, threads, [&](int row) {
        const int j = row % s.height, k = row / s.height;
        detail::ConeSearch search(tests);
        for (int i = 0; i < s.width; ++i) {
            search.reset(m.cap);
            // The floor.
            const detail::Box floorBox{{-1e9, -1e9, bottom - (k + 1.0)}, {1e9, 1e9, 0.0 - k}};
            search.offer(floorBox, search.open(floorBox, detail::boxDistance(floorBox)));
            search.settle();
            const int maxShell = static_cast<int>(std::ceil(m.cap)) + 1;
            const auto visit = [&](int di, int dj, int dk) {
                const int vk = k + dk;
                if (!s.voxelSolid[s.voxelIndex(i + di, j + dj, vk)]) return;
                const detail::Box vb{{di - 1.0, dj - 1.0, dk - 1.0}, {di + 1.0, dj + 1.0, dk + 1.0}};
                const std::uint32_t open = search.open(vb, detail::boxDistance(vb)); // the cones this voxel may improve
                if (open == 0) return;
                for (int e = 0; e < S * S * S; ++e) {
                    const int a = e % S, b = e / S % S, z = e / (S * S);
                    if (!s.subSolid((i + di) * S + a, (j + dj) * S + b, vk * S + z)) continue;
                    const glm::dvec3 l(di + a * h, dj + b * h, dk + z * h);
                    search.offer(detail::Box{l - 1.0, l + h}, open);
                }
                search.settle();
            };
            for (int r = 0; r <= maxShell && r - 1 < search.worst; ++r)
                for (int dk = -r; dk <= r; ++dk) {
                    if (k + dk < 0 || k + dk >= s.layers) continue;
                    for (int dj = -r; dj <= r; ++dj) {
                        if (std::abs(dk) == r || std::abs(dj) == r) { // a whole row of the shell
                            for (int di = -r; di <= r; ++di) visit(di, dj, dk);
                        } else { // only its two ends
                            visit(-r, dj, dk);
                            if (r > 0) visit(r, dj, dk);
                        }
                    }
                }
            for (int c = 0; c < C; ++c) m.d[m.index(c, i, j, k)] = detail::floatBelow(search.best[static_cast<std::size_t>(c)]);
        }
    });
    return m;
}

} // namespace dispmap
