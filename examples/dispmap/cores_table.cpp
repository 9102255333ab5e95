// `dispmap bench --only cores`: every parallel stage run on one thread and on all cores in the
// same run (the machine is shared and noisy: the ratio is the figure, not the seconds), with a
// bit-for-bit comparison of the two results; and the set-up cost of the auto-normal analysis,
// which now runs only when auto normals are asked for.
#include "cores_table.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <iomanip>
#include <map>
#include <memory>
#include <vector>

#include "maps_table.h"
#include "meso.h"
#include "text_format.h"
#include "dispmap/core/parallel.h"
#include "dispmap/io/image_files.h"
#include "dispmap/meso/march.h"
#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/tessellator.h"
#include "dispmap/surface/uv_map.h"

namespace dispmap::figures {

double secondsOf(const std::function<void()>& f) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

namespace {

template <class T, class A, class B> bool bitsEqual(const std::vector<T, A>& a, const std::vector<T, B>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool tilesEqual(const TileSet& a, const TileSet& b) {
    if (a.tileCount() != b.tileCount()) return false;
    for (std::size_t t = 0; t < a.tiles.size(); ++t)
        if (a.tiles[t].k != b.tiles[t].k || !bitsEqual(a.tiles[t].coefficients, b.tiles[t].coefficients)) return false;
    return true;
}

bool meshesEqual(const TriangleMesh& a, const TriangleMesh& b) {
    return bitsEqual(a.positions, b.positions) && bitsEqual(a.normals, b.normals) && a.triangles == b.triangles &&
           a.faces == b.faces;
}

bool mesoEqual(const std::map<std::string, MesoMaps>& a, const std::map<std::string, MesoMaps>& b) {
    if (a.size() != b.size()) return false;
    for (const auto& [name, x] : a) {
        const auto it = b.find(name);
        if (it == b.end()) return false;
        const MesoMaps& y = it->second;
        if (!bitsEqual(x.distance.d, y.distance.d) || x.ddm.grid != y.ddm.grid || !bitsEqual(x.ddm.atlas, y.ddm.atlas)) return false;
    }
    return true;
}

struct Row {
    std::string stage, work;
    double one = 0, all = 0;
    bool identical = false;
};

} // namespace

void printCoresTable(std::ostream& out, const CoresTableArgs& a) {
    const int cores = allCores();
    const ControlMesh spot = ControlMesh::fromObjFile(a.dataDir + "/spot_control_mesh.obj");
    HeightMaps brick;
    brick.images[0] = std::make_shared<const HeightImage>(readHeightImage(a.dataDir + "/skimage_brick.png"));
    const auto uvs = std::make_shared<const UvMap>(spot, UvInterpolation::Linear);
    const int k = a.quick ? 4 : 6;
    std::vector<Row> rows;

    // 1. Tile build: sampling the map, the fit's sweeps, the mips.
    TileSet tiles1, tilesN;
    Row build{"tile build (sample, fit, mips)", "Spot, brick map, 2^" + std::to_string(k) + " tiles"};
    build.one = secondsOf([&] { tiles1 = spotBrickTiles(spot, uvs, brick, k, 1); });
    build.all = secondsOf([&] { tilesN = spotBrickTiles(spot, uvs, brick, k, 0); });
    build.identical = tilesEqual(tiles1, tilesN);
    std::size_t samples = 0;
    for (const Tile& t : tiles1.tiles) samples += std::size_t{1} << (2 * t.k);
    rows.push_back(build);

    // 2. Set-up of the displaced surface, and the auto-normal analysis it no longer runs.
    const BaseSurface base(spot);
    DisplacedSurfaceOptions one;
    one.threads = 1;
    std::unique_ptr<DisplacedSurface> s1, sN;
    const double construct = secondsOf([&] { s1 = std::make_unique<DisplacedSurface>(base, tiles1, one); });
    Row analysis{"auto-normal analysis (17^2 a face)", "Spot, on first use of auto normals"};
    analysis.one = secondsOf([&] { (void)s1->autoFaces(); });
    sN = std::make_unique<DisplacedSurface>(base, tiles1);
    analysis.all = secondsOf([&] { (void)sN->autoFaces(); });
    analysis.identical = s1->autoFaces() == sN->autoFaces();
    rows.push_back(analysis);

    // 3. Tessellation: connectivity on one thread, vertices on all.
    const double factor = a.quick ? 8 : 32;
    TessellateOptions to;
    to.threads = 1;
    const TessFactors factors = uniformTessFactors(base, factor);
    TriangleMesh m1, mN;
    Row tess{"tessellation (approximate normals)", ""};
    tess.one = secondsOf([&] { m1 = tessellate(*s1, factors, to); });
    to.threads = 0;
    tess.all = secondsOf([&] { mN = tessellate(*s1, factors, to); });
    tess.identical = meshesEqual(m1, mN);
    tess.work = "Spot, factor " + fixed(factor, 0) + ", " + std::to_string(m1.triangleCount()) + " triangles, first call";
    rows.push_back(tess);
    // Repeated: what a renderer re-tessellating every frame sees. A first call also pays the
    // kernel's first touch of its output's pages (sized on all cores, but bound by the kernel);
    // later calls get memory the allocator already holds. Best of seven, each count (calls of 10-25 ms
    // on a shared machine: best of three moved the ratio by about 0.2 from run to run).
    Row again{"tessellation, repeated", "the same, best of 7 calls"};
    again.one = again.all = 1e300;
    for (int run = 0; run < 7; ++run) {
        to.threads = 1;
        m1 = TriangleMesh{};
        again.one = std::min(again.one, secondsOf([&] { m1 = tessellate(*s1, factors, to); }));
        to.threads = 0;
        mN = TriangleMesh{};
        again.all = std::min(again.all, secondsOf([&] { mN = tessellate(*s1, factors, to); }));
    }
    again.identical = meshesEqual(m1, mN);
    rows.push_back(again);

    // 4. Mesostructure maps: the bricks scene's cone sets (distance map, DDM, quadrics).
    const MesoScene bricks = mesoScenes(a.dataDir).front();
    const std::vector<std::string> coneSets = a.quick ? std::vector<std::string>{"4x1"} : tableConeSets();
    std::map<std::string, MesoMaps> meso1, mesoN;
    Row meso{"mesostructure maps", "bricks 128x128x16, " + std::to_string(coneSets.size()) + " cone set" + (coneSets.size() > 1 ? "s" : "")};
    meso.one = secondsOf([&] { meso1 = buildConeSetMaps(bricks.field, coneSets, 1); });
    meso.all = secondsOf([&] { mesoN = buildConeSetMaps(bricks.field, coneSets, 0); });
    meso.identical = mesoEqual(meso1, mesoN);
    rows.push_back(meso);

    // 5. Locality: random points on a tile set larger than the cache, evaluated in the order
    //    given and face by face (evaluateBatch), on one thread.
    const int kBig = a.quick ? 5 : 8;
    const TileSet big = spotBrickTiles(spot, uvs, brick, kBig, 0);
    std::size_t bigBytes = 0;
    for (const Tile& t : big.tiles) bigBytes += t.coefficients.size() * sizeof(float);
    const DisplacedSurface bigSurface(base, big, one);
    std::vector<SurfacePoint<double>> points(a.quick ? 20000 : 400000);
    std::uint64_t state = 0x9E3779B97F4A7C15ull;
    auto next = [&] { // splitmix64: the same points on every machine
        state += 0x9E3779B97F4A7C15ull;
        std::uint64_t z = state;
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    };
    for (SurfacePoint<double>& p : points) {
        p.face = static_cast<int>(next() % static_cast<std::uint64_t>(base.faceCount()));
        p.u = static_cast<double>(next() >> 11) * 0x1.0p-53;
        p.v = static_cast<double>(next() >> 11) * 0x1.0p-53;
    }
    std::vector<SurfaceSample<double>> given(points.size()), batched;
    const double givenS = secondsOf([&] {
        for (std::size_t i = 0; i < points.size(); ++i)
            given[i] = bigSurface.evaluate<double>(points[i].face, points[i].u, points[i].v, NormalMode::Approximate);
    });
    const double batchS = secondsOf([&] { bigSurface.evaluateBatch(points, NormalMode::Approximate, batched, 1); });
    // The tile lookups alone (TileSet::evaluateD1, the finest level), in the order given and
    // face by face: the part of an evaluation that waits on memory.
    std::vector<std::size_t> byFace(points.size());
    for (std::size_t i = 0; i < byFace.size(); ++i) byFace[i] = i;
    std::stable_sort(byFace.begin(), byFace.end(), [&](std::size_t x, std::size_t y) { return points[x].face < points[y].face; });
    glm::dvec3 sinkGiven(0.0), sinkSorted(0.0);
    const double tileGivenS = secondsOf([&] {
        for (const SurfacePoint<double>& p : points) sinkGiven += big.evaluateD1(p.face, 0, glm::dvec2(p.u, p.v));
    });
    const double tileSortedS = secondsOf([&] {
        for (std::size_t i : byFace) sinkSorted += big.evaluateD1(points[i].face, 0, glm::dvec2(points[i].u, points[i].v));
    });
    bool sameLookups = batched.size() == given.size();
    for (std::size_t i = 0; sameLookups && i < given.size(); ++i)
        sameLookups = std::memcmp(&given[i].position, &batched[i].position, sizeof(glm::dvec3)) == 0 &&
                      std::memcmp(&given[i].normal, &batched[i].normal, sizeof(glm::dvec3)) == 0;

    out << "All cores against one thread, measured in one run (" << cores << " cores here; speed-up = 1-thread time / "
        << cores << "-thread time; identical: the two results compared bit for bit):\n\n";
    out << "| stage | work | 1 thread s | " << cores << " threads s | speed-up | identical |\n|---|---|---|---|---|---|\n";
    std::unique_ptr<std::ofstream> csv;
    if (!a.csv.empty()) {
        csv = std::make_unique<std::ofstream>(a.csv);
        *csv << "stage,work,seconds_1,seconds_all,threads,speedup,identical\n";
    }
    for (const Row& r : rows) {
        out << "| " << r.stage << " | " << r.work << " | " << fixed(r.one, 3) << " | " << fixed(r.all, 3) << " | "
            << fixed(r.one / std::max(r.all, 1e-9), 2) << "x | " << (r.identical ? "yes" : "NO") << " |\n";
        if (csv)
            *csv << '"' << r.stage << "\",\"" << r.work << "\"," << r.one << "," << r.all << "," << cores << ","
                 << r.one / std::max(r.all, 1e-9) << "," << (r.identical ? 1 : 0) << "\n";
    }
    out << "\nTile fit rate: " << samples << " samples in " << fixed(build.one, 3) << " s on one thread = "
        << fixed(static_cast<double>(samples) / build.one / 1e6, 2) << " M samples/s per core (sampling the map included).\n";
    out << "Lookups: " << points.size() << " random points on Spot's 2^" << kBig << " tiles (" << fixed(static_cast<double>(bigBytes) / 1048576.0, 1)
        << " MiB of texels), one thread: " << fixed(givenS / static_cast<double>(points.size()) * 1e9, 0)
        << " ns a point in the order given, " << fixed(batchS / static_cast<double>(points.size()) * 1e9, 0)
        << " ns face by face (evaluateBatch): " << fixed(givenS / std::max(batchS, 1e-9), 2) << "x, "
        << (sameLookups ? "identical" : "DIFFERENT") << "; the tile lookups alone (evaluateD1): "
        << fixed(tileGivenS / static_cast<double>(points.size()) * 1e9, 0) << " ns in the order given, "
        << fixed(tileSortedS / static_cast<double>(points.size()) * 1e9, 0) << " ns face by face: "
        << fixed(tileGivenS / std::max(tileSortedS, 1e-9), 2) << "x (sums " << (glm::length(sinkGiven - sinkSorted) < 1e-6 * glm::length(sinkGiven) + 1e-300 ? "agree" : "DIFFER") << ").\n";
    out << "Set-up of DisplacedSurface on Spot: " << fixed(construct * 1e3, 2)
        << " ms without the auto-normal analysis (which it ran every time before; " << fixed(analysis.one * 1e3, 1)
        << " ms on one thread, now only when auto normals are first used).\n";
}

} // namespace dispmap::figures
