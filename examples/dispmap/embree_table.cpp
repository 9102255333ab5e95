// `dispmap bench --only embree`: dispmap and Embree 3 on the same cage and the same D.
//
// Embree's side: RTC_GEOMETRY_TYPE_SUBDIVISION with the cage's faces, its creases and corners as
// Embree's edge and vertex crease weights (OpenSubdiv's sharpness 10 and above: infinite), its
// holes and boundary rule, a uniform tessellation rate T (T quads along every base edge, as
// dispmap's factor T gives T segments), and a displacement callback that moves each of Embree's
// points along Embree's unit normal by dispmap's D at that (face, u, v): the tiles both sides
// read. Embree displaces at commit, so its commit is its whole set-up and tessellation.
//
// Accuracy, measured the same way for both: points on the double-precision displaced surface
// (DisplacedSurface::evaluate, accurate normals); from each, rays along +N and -N; the distance
// to the nearest hit of the tessellated surface (dispmap's triangles in an Embree triangle
// scene, Embree's own displaced grids) is that point's error, relative to the cage's
// bounding-box diagonal.
#include "embree_table.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <vector>

#include "cages_table.h"
#include "cores_table.h"
#include "maps_table.h"
#include "text_format.h"
#include "dispmap/bake/ray_scene.h"
#include "dispmap/io/image_files.h"
#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/tessellator.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/surface/uv_map.h"

namespace dispmap::figures {

namespace {

/// Timed runs per measurement: three, or one when a set-up takes over half a second, or a
/// tessellation cell (fresh, again and Embree's commit together) over kLongCell. The least is
/// kept (a shared machine: the least is the run least disturbed); both sides of a comparison get
/// the same number, and nothing is freed inside a timed run. A cell's first run at hundreds of
/// MiB also pays for the machine finding huge pages the first time (the bishop at 64: 1.57 s for
/// its first fresh tessellation, 0.50 s for the next), hence three runs up to seconds.
constexpr int kRuns = 3;
constexpr double kLongRun = 0.5;
constexpr double kLongCell = 6.0;

struct EmbreeDeleter {
    void operator()(RTCDevice d) const { rtcReleaseDevice(d); }
    void operator()(RTCScene s) const { rtcReleaseScene(s); }
};
using DevicePtr = std::unique_ptr<RTCDeviceTy, EmbreeDeleter>;
using ScenePtr = std::unique_ptr<RTCSceneTy, EmbreeDeleter>;

void checkEmbree(RTCDevice device, const std::string& what) {
    const RTCError e = rtcGetDeviceError(device);
    if (e != RTC_ERROR_NONE) throw Error("Embree: " + what + " failed (error " + std::to_string(static_cast<int>(e)) + ")");
}

/// What the displacement callback reads. `probe` (set on an untimed commit only) records how
/// far Embree's limit surface lies from dispmap's base surface at Embree's own points, and
/// whether Embree's normal points the way dispmap's does: the check that (face, u, v) is read
/// the same on both sides.
struct Probe {
    std::mutex lock;
    double maxGap = 0;
    std::uint64_t points = 0, flipped = 0;
};
struct DisplaceContext {
    const ControlMesh* mesh = nullptr;
    const DisplacedSurface* surface = nullptr;
    std::vector<int> ptexBase;
    float sign = 1;
    Probe* probe = nullptr;
};

/// Embree's (u, v) on face f as dispmap's (Ptex face, u, v). A quad: the same (corner 0,
/// u towards corner 1, v towards corner 3). Other faces: Embree encodes sub-face i of the face's
/// one-step split (the sub-face at corner i, Ptex's order) as U = 2 (i mod 4) + u + 0.5,
/// V = 2 floor(i / 4) + v + 0.5 (RTC_GEOMETRY_TYPE_SUBDIVISION, "Parametrization").
void embreeToPtex(const DisplaceContext& c, int f, int size, float U, float V, int& face, double& u, double& v) {
    face = c.ptexBase[static_cast<std::size_t>(f)];
    u = static_cast<double>(U);
    v = static_cast<double>(V);
    if (size != 4) {
        const double l = std::floor(0.5 * u), h = std::floor(0.5 * v);
        face += static_cast<int>(4 * h + l);
        u = 2.0 * (0.5 * u - l) - 0.5;
        v = 2.0 * (0.5 * v - h) - 0.5;
    }
    u = std::clamp(u, 0.0, 1.0);
    v = std::clamp(v, 0.0, 1.0);
}

void displace(const RTCDisplacementFunctionNArguments* a) {
    const DisplaceContext& c = *static_cast<const DisplaceContext*>(a->geometryUserPtr);
    const int f = static_cast<int>(a->primID);
    const int size = c.mesh->description().faceSizes[static_cast<std::size_t>(f)];
    for (unsigned i = 0; i < a->N; ++i) {
        int face = 0;
        double u = 0, v = 0;
        embreeToPtex(c, f, size, a->u[i], a->v[i], face, u, v);
        const double d = c.surface->displacement<double>(face, u, v).x;
        if (c.probe) {
            const BaseSample<double> s = c.surface->base().evaluate<double>(face, u, v, false);
            const glm::dvec3 p(a->P_x[i], a->P_y[i], a->P_z[i]), ng(a->Ng_x[i], a->Ng_y[i], a->Ng_z[i]);
            const std::lock_guard<std::mutex> hold(c.probe->lock);
            c.probe->maxGap = std::max(c.probe->maxGap, glm::length(p - s.p));
            c.probe->points += 1;
            if (glm::dot(ng, glm::cross(s.du, s.dv)) < 0) c.probe->flipped += 1;
        }
        const float k = c.sign * static_cast<float>(d);
        a->P_x[i] += k * a->Ng_x[i];
        a->P_y[i] += k * a->Ng_y[i];
        a->P_z[i] += k * a->Ng_z[i];
    }
}

/// Embree's subdivision surface of `mesh`, tessellated at `rate` and displaced by `c`.
ScenePtr commitEmbree(RTCDevice device, const ControlMesh& mesh, DisplaceContext& c, float rate) {
    const MeshDescription& d = mesh.description();
    if (d.creasing != Sdc::Options::CREASE_UNIFORM || d.triangles != Sdc::Options::TRI_SUB_CATMARK)
        throw ArgumentError(d.name + ": Embree has no Chaikin creasing and no smooth-triangle rule; the comparison needs the plain rules");
    ScenePtr scene(rtcNewScene(device));
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_SUBDIVISION);
    checkEmbree(device, "a subdivision geometry");
    auto newBuffer = [&](RTCBufferType type, RTCFormat format, std::size_t bytes, std::size_t count) {
        void* p = rtcSetNewGeometryBuffer(g, type, 0, format, bytes, count);
        if (!p) {
            rtcReleaseGeometry(g);
            checkEmbree(device, "a geometry buffer");
            throw Error("Embree: cannot allocate a geometry buffer");
        }
        return p;
    };
    auto* faces = static_cast<unsigned*>(newBuffer(RTC_BUFFER_TYPE_FACE, RTC_FORMAT_UINT, sizeof(unsigned), d.faceSizes.size()));
    for (std::size_t f = 0; f < d.faceSizes.size(); ++f) faces[f] = static_cast<unsigned>(d.faceSizes[f]);
    auto* index = static_cast<unsigned*>(newBuffer(RTC_BUFFER_TYPE_INDEX, RTC_FORMAT_UINT, sizeof(unsigned), d.faceVertices.size()));
    for (std::size_t i = 0; i < d.faceVertices.size(); ++i) index[i] = static_cast<unsigned>(d.faceVertices[i]);
    auto* vertex = static_cast<float*>(newBuffer(RTC_BUFFER_TYPE_VERTEX, RTC_FORMAT_FLOAT3, 3 * sizeof(float), d.positions.size()));
    for (std::size_t i = 0; i < d.positions.size(); ++i)
        for (int k = 0; k < 3; ++k) vertex[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(d.positions[i][k]);
    // OpenSubdiv's sharpness 10 is infinitely sharp; Embree's is infinity.
    auto weight = [](float s) { return s >= 10.0f ? std::numeric_limits<float>::infinity() : s; };
    if (!d.creaseWeights.empty()) {
        auto* pairs = static_cast<unsigned*>(
            newBuffer(RTC_BUFFER_TYPE_EDGE_CREASE_INDEX, RTC_FORMAT_UINT2, 2 * sizeof(unsigned), d.creaseWeights.size()));
        auto* w = static_cast<float*>(newBuffer(RTC_BUFFER_TYPE_EDGE_CREASE_WEIGHT, RTC_FORMAT_FLOAT, sizeof(float), d.creaseWeights.size()));
        for (std::size_t i = 0; i < d.creaseWeights.size(); ++i) {
            pairs[2 * i] = static_cast<unsigned>(d.creaseVertexPairs[2 * i]);
            pairs[2 * i + 1] = static_cast<unsigned>(d.creaseVertexPairs[2 * i + 1]);
            w[i] = weight(d.creaseWeights[i]);
        }
    }
    if (!d.cornerWeights.empty()) {
        auto* v = static_cast<unsigned*>(newBuffer(RTC_BUFFER_TYPE_VERTEX_CREASE_INDEX, RTC_FORMAT_UINT, sizeof(unsigned), d.cornerWeights.size()));
        auto* w = static_cast<float*>(newBuffer(RTC_BUFFER_TYPE_VERTEX_CREASE_WEIGHT, RTC_FORMAT_FLOAT, sizeof(float), d.cornerWeights.size()));
        for (std::size_t i = 0; i < d.cornerWeights.size(); ++i) {
            v[i] = static_cast<unsigned>(d.cornerVertices[i]);
            w[i] = weight(d.cornerWeights[i]);
        }
    }
    if (!d.holes.empty()) {
        auto* h = static_cast<unsigned*>(newBuffer(RTC_BUFFER_TYPE_HOLE, RTC_FORMAT_UINT, sizeof(unsigned), d.holes.size()));
        for (std::size_t i = 0; i < d.holes.size(); ++i) h[i] = static_cast<unsigned>(d.holes[i]);
    }
    rtcSetGeometrySubdivisionMode(g, 0,
                                  d.boundary == Sdc::Options::VTX_BOUNDARY_NONE              ? RTC_SUBDIVISION_MODE_NO_BOUNDARY
                                  : d.boundary == Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER ? RTC_SUBDIVISION_MODE_PIN_CORNERS
                                                                                             : RTC_SUBDIVISION_MODE_SMOOTH_BOUNDARY);
    rtcSetGeometryTessellationRate(g, rate);
    rtcSetGeometryUserData(g, &c);
    rtcSetGeometryDisplacementFunction(g, displace);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene.get(), g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene.get());
    checkEmbree(device, "the subdivision scene's commit");
    return scene;
}

struct Accuracy {
    double rms = 0, p99 = 0, max = 0; ///< relative to the cage's bounding-box diagonal
    int misses = 0;          ///< points with no hit within `reach` either way
};

struct Reference {
    std::vector<glm::dvec3> p, n;
};

/// `hit(org, dir, tfar)`: the distance to the first hit along dir, or a negative value.
Accuracy measure(const Reference& ref, double diag, const std::function<float(const glm::vec3&, const glm::vec3&, float)>& hit) {
    Accuracy a;
    const float reach = static_cast<float>(0.05 * diag);
    double sum = 0;
    std::vector<double> errors;
    for (std::size_t i = 0; i < ref.p.size(); ++i) {
        const glm::vec3 org(ref.p[i]), dir(ref.n[i]);
        const float up = hit(org, dir, reach), down = hit(org, -dir, reach);
        float t = -1;
        if (up >= 0) t = up;
        if (down >= 0 && (t < 0 || down < t)) t = down;
        if (t < 0) {
            ++a.misses;
            continue;
        }
        const double e = static_cast<double>(t) / diag;
        sum += e * e;
        errors.push_back(e);
    }
    if (!errors.empty()) {
        std::sort(errors.begin(), errors.end());
        a.rms = std::sqrt(sum / static_cast<double>(errors.size()));
        a.p99 = errors[std::min(errors.size() - 1, errors.size() * 99 / 100)];
        a.max = errors.back();
    }
    return a;
}

float embreeHit(RTCScene scene, const glm::vec3& org, const glm::vec3& dir, float tfar) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh = embreeRay(org, dir, 0.0f, tfar);
    rtcIntersect1(scene, &ctx, &rh);
    return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? -1.0f : rh.ray.tfar;
}

struct Case {
    std::string name, source;
    std::shared_ptr<const ControlMesh> mesh;
    std::function<TileSet(const BaseSurface& base, int threads)> tiles;
    std::vector<double> factors;
};

/// A smooth D in space, the same across faces: A sin(2 pi x / L) sin(2 pi y / L) sin(2 pi z / L) at
/// the base surface's point, with A = 0.4 % and L = 10 % of the cage's diagonal (slopes below
/// 0.44, so the displaced surface stays a gentle relief at every cage density).
std::function<TileSet(const BaseSurface&, int)> spaceWavesTiles(std::shared_ptr<const ControlMesh> mesh, int k) {
    return [mesh, k](const BaseSurface& base, int threads) {
        const double diag = cageDiagonal(*mesh), amplitude = 0.004 * diag, w = 6.283185307179586 / (0.1 * diag);
        BuildOptions bo;
        bo.threads = threads;
        return buildTiles(*mesh, uniformTileSizes(*mesh, k), FunctionSource([&base, amplitude, w](int f, double u, double v) {
                              const glm::dvec3 p = base.evaluate<double>(f, u, v, false).p;
                              return amplitude * std::sin(w * p.x) * std::sin(w * p.y) * std::sin(w * p.z);
                          }),
                          bo);
    };
}

std::vector<Case> cases(const EmbreeTableArgs& a) {
    std::vector<Case> out;
    auto spot = std::make_shared<const ControlMesh>(ControlMesh::fromObjFile(a.dataDir + "/spot_control_mesh.obj"));
    auto brick = std::make_shared<HeightMaps>();
    brick->images[0] = std::make_shared<const HeightImage>(readHeightImage(a.dataDir + "/skimage_brick.png"));
    auto uvs = std::make_shared<const UvMap>(*spot, UvInterpolation::Linear);
    const int kSpot = a.quick ? 4 : 6;
    out.push_back({"Spot", "brick map, 2^" + std::to_string(kSpot) + " tiles", spot,
                   [spot, uvs, brick, kSpot](const BaseSurface&, int threads) { return spotBrickTiles(*spot, uvs, *brick, kSpot, threads); },
                   a.quick ? std::vector<double>{2, 8} : std::vector<double>{2, 4, 8, 16, 32, 64}});
    if (a.quick) return out;
    auto bishop = std::make_shared<const ControlMesh>(ControlMesh::fromObjFile(a.dataDir + "/catmark_bishop.obj"));
    out.push_back({"bishop (creases up to 6)", "waves in space, 2^5 tiles", bishop, spaceWavesTiles(bishop, 5), {2, 4, 8, 16, 32, 64}});
    const std::string fandisk = a.denseDir + "/cgal_fandisk.off";
    if (std::filesystem::exists(fandisk)) {
        auto cage = std::make_shared<const ControlMesh>(denseCage(fandisk, "fandisk"));
        out.push_back({"fandisk cage (" + std::to_string(cage->base().GetNumFaces()) + " triangles)",
                       "waves in space, 2^3 tiles", cage, spaceWavesTiles(cage, 3), {4, 8}});
    }
    // The 50k-face class: the bunny decimated to 52000 triangles (156k Ptex faces).
    const std::string bunny = a.denseDir + "/cgal_bunny00.off";
    if (std::filesystem::exists(bunny)) {
        auto cage = std::make_shared<const ControlMesh>(decimatedCage(bunny, 52000, "bunny"));
        out.push_back({cage->description().name, "waves in space, 2^3 tiles", cage, spaceWavesTiles(cage, 3), {4, 8}});
    }
    return out;
}

} // namespace

void printEmbreeTable(std::ostream& out, const EmbreeTableArgs& a) {
    // One thread: Embree sizes its task arena by the largest "threads" of the devices alive, so
    // the ray scenes of the accuracy measurement (RayScene, a device each, all threads) are gone
    // before the next timed commit (each lives inside one factor's loop body).
    DevicePtr device(rtcNewDevice("threads=1"));
    if (!device) throw Error("Embree: cannot create a device (error " + std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
    std::unique_ptr<std::ofstream> csv;
    if (!a.csv.empty()) {
        csv = std::make_unique<std::ofstream>(a.csv);
        *csv << "cage,factor,triangles,dispmap_setup_s,dispmap_tessellate_s,dispmap_again_s,embree_commit_s,tessellate_ratio,total_ratio,"
                "dispmap_rms,dispmap_p99,dispmap_max,dispmap_missed,embree_rms,embree_p99,embree_max,embree_missed\n";
    }
    out << "dispmap against Embree " << RTC_VERSION_MAJOR << "." << RTC_VERSION_MINOR << "." << RTC_VERSION_PATCH
        << " (subdivision geometry, the same cage and D), one thread each, measured in one run. dispmap set-up = base\n"
        << "surface + tile build + DisplacedSurface; Embree's commit (scene, geometry, tessellation at rate T with the\n"
        << "displacement callback, BVH) is its whole set-up. Ratios are dispmap / Embree: below 1, dispmap is faster.\n"
        << "dispmap tessellates into a new mesh (its memory's first touch included, as Embree's into a new scene) and\n"
        << "again into the mesh of the run before (its arrays kept: none reallocated, their pages already touched).\n"
        << "Error: distance from points of the double-precision displaced surface to each tessellated surface, along\n"
        << "the surface normal (the nearer hit of the rays along +N and -N), RMS / 99th percentile, relative to the cage's\n"
        << "bounding-box diagonal; missed: no hit within 5 % of the diagonal either way (steep walls, thin parts).\n\n";
    const int points = a.quick ? 2000 : 20000;
    for (const Case& c : cases(a)) {
        const ControlMesh& mesh = *c.mesh;
        const double diag = cageDiagonal(mesh);
        std::unique_ptr<BaseSurface> base;
        TileSet tiles;
        std::unique_ptr<DisplacedSurface> surface;
        DisplacedSurfaceOptions one;
        one.threads = 1;
        double baseS = 1e300, tilesS = 1e300, surfaceS = 1e300;
        for (int run = 0; run < kRuns; ++run) {
            surface.reset();
            tiles = TileSet{};
            base.reset();
            baseS = std::min(baseS, secondsOf([&] { base = std::make_unique<BaseSurface>(mesh); }));
            tilesS = std::min(tilesS, secondsOf([&] { tiles = c.tiles(*base, 1); }));
            surfaceS = std::min(surfaceS, secondsOf([&] { surface = std::make_unique<DisplacedSurface>(*base, tiles, one); }));
            if (baseS + tilesS + surfaceS > kLongRun) break;
        }
        const double setupS = baseS + tilesS + surfaceS;

        // The reference points: uniform over the Ptex faces (splitmix64, the same on every machine).
        Reference ref;
        std::uint64_t state = 0x243F6A8885A308D3ull;
        auto next = [&] {
            state += 0x9E3779B97F4A7C15ull;
            std::uint64_t z = state;
            z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
            z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
            return z ^ (z >> 31);
        };
        for (int i = 0; i < points; ++i) {
            const int face = static_cast<int>(next() % static_cast<std::uint64_t>(base->faceCount()));
            const double u = static_cast<double>(next() >> 11) * 0x1.0p-53, v = static_cast<double>(next() >> 11) * 0x1.0p-53;
            if (base->isHole(face)) continue;
            const SurfaceSample<double> s = surface->evaluate<double>(face, u, v, NormalMode::Accurate);
            ref.p.push_back(s.position);
            ref.n.push_back(s.normal);
        }

        DisplaceContext ctx;
        ctx.mesh = &mesh;
        ctx.surface = surface.get();
        for (int f = 0; f < mesh.base().GetNumFaces(); ++f) ctx.ptexBase.push_back(mesh.ptex().GetFaceId(f));
        // An untimed commit that checks the parameter mapping and Embree's normal orientation.
        Probe probe;
        ctx.probe = &probe;
        (void)commitEmbree(device.get(), mesh, ctx, 2.0f);
        ctx.probe = nullptr;
        const bool flip = 2 * probe.flipped > probe.points;
        ctx.sign = flip ? -1.0f : 1.0f;

        out << "**" << c.name << "** (" << mesh.base().GetNumFaces() << " faces, " << base->faceCount() << " Ptex faces; D: " << c.source
            << "). dispmap set-up " << fixed(setupS * 1e3, 1) << " ms (base surface " << fixed(baseS * 1e3, 1) << ", tiles "
            << fixed(tilesS * 1e3, 1) << ", surface " << fixed(surfaceS * 1e3, 1) << "). Embree's limit surface at its "
            << probe.points << " displaced points: within " << sci(probe.maxGap / diag) << " of dispmap's base surface; its normal "
            << (flip ? "opposite to" : "along") << " dispmap's s_u x s_v at ";
        const std::uint64_t agreeing = flip ? probe.flipped : probe.points - probe.flipped;
        if (agreeing == probe.points)
            out << "all of them";
        else
            out << agreeing << " of them";
        out << (flip ? " (displaced along -Ng)" : "") << ".\n\n";
        out << "| factor | triangles (dispmap) | dispmap tessellate ms | again, same mesh ms | Embree commit ms | tessellate ratio "
               "| again ratio | set-up + tessellate ratio | dispmap error RMS / p99 | Embree error RMS / p99 |\n"
               "|---|---|---|---|---|---|---|---|---|---|\n";
        TessellateOptions to;
        to.threads = 1;
        double firstCommit = 0;
        for (double T : c.factors) {
            const TessFactors factors = uniformTessFactors(*base, T);
            TriangleMesh m;
            ScenePtr scene;
            // Fresh: into a new mesh, as Embree's commit into a new scene (both take their memory's
            // first touch). Again: the same tessellation into the mesh of the run before, whose
            // arrays are kept (Tessellator::tessellate(TriangleMesh&): an application tessellating
            // again as its factors change).
            double tessS = 1e300, againS = 1e300, commitS = 1e300;
            const Tessellator tessellator(*surface, factors, to);
            for (int run = 0; run < kRuns; ++run) {
                m = TriangleMesh{};
                scene.reset();
                // The fresh run includes making the Tessellator (the factors' checks), as the
                // previous tables' runs did; "again" reuses it, as an application would.
                tessS = std::min(tessS, secondsOf([&] { m = Tessellator(*surface, factors, to).tessellate(); }));
                againS = std::min(againS, secondsOf([&] { tessellator.tessellate(m); }));
                commitS = std::min(commitS, secondsOf([&] { scene = commitEmbree(device.get(), mesh, ctx, static_cast<float>(T)); }));
                if (tessS + againS + commitS > kLongCell) break;
            }
            if (firstCommit == 0) firstCommit = commitS;
            std::vector<glm::vec3> positions(m.positions.begin(), m.positions.end());
            std::vector<glm::uvec3> triangles(m.triangles.begin(), m.triangles.end());
            const RayScene ours(positions, triangles);
            const Accuracy da = measure(ref, diag, [&](const glm::vec3& o, const glm::vec3& d, float tfar) {
                const RayScene::Hit h = ours.intersect(o, d, 0.0f, tfar);
                return h.hit ? h.t : -1.0f;
            });
            const Accuracy ea = measure(ref, diag, [&](const glm::vec3& o, const glm::vec3& d, float tfar) { return embreeHit(scene.get(), o, d, tfar); });
            auto acc = [](const Accuracy& x) {
                return sci(x.rms) + " / " + sci(x.p99) + (x.misses ? " (" + std::to_string(x.misses) + " missed)" : std::string());
            };
            out << "| " << fixed(T, 0) << " | " << m.triangleCount() << " | " << fixed(tessS * 1e3, 2) << " | " << fixed(againS * 1e3, 2)
                << " | " << fixed(commitS * 1e3, 2) << " | " << fixed(tessS / commitS, 2) << "x | " << fixed(againS / commitS, 2) << "x | "
                << fixed((setupS + tessS) / commitS, 2) << "x | " << acc(da) << " | " << acc(ea) << " |\n";
            if (csv)
                *csv << '"' << c.name << "\"," << T << "," << m.triangleCount() << "," << setupS << "," << tessS << "," << againS << "," << commitS << ","
                     << tessS / commitS << "," << (setupS + tessS) / commitS << "," << da.rms << "," << da.p99 << "," << da.max << ","
                     << da.misses << "," << ea.rms << "," << ea.p99 << "," << ea.max << "," << ea.misses << "\n";
        }
        {
            // What the huge-page hint on new output arrays saves (TessellateOptions::hugePages),
            // at the largest factor, the two interleaved, each freed before the next; always
            // three runs each (the table's rows stop after one run over half a second).
            const double T = c.factors.back();
            TessellateOptions small = to;
            small.hugePages = false;
            const TessFactors factors = uniformTessFactors(*base, T);
            const Tessellator hinted(*surface, factors, to), plain(*surface, factors, small);
            double withS = 1e300, withoutS = 1e300;
            for (int run = 0; run < kRuns; ++run) {
                TriangleMesh m;
                withS = std::min(withS, secondsOf([&] { m = hinted.tessellate(); }));
                m = TriangleMesh{};
                withoutS = std::min(withoutS, secondsOf([&] { m = plain.tessellate(); }));
            }
            out << "\nFirst touch at factor " << fixed(T, 0) << ": a new mesh in " << fixed(withS * 1e3, 2)
                << " ms with the huge-page hint on its arrays, " << fixed(withoutS * 1e3, 2) << " ms without (TessellateOptions::hugePages; "
                << fixed(withoutS / withS, 2) << "x; least of three runs each, interleaved).\n";
        }
        out << "\nSet-up ratio (dispmap set-up / Embree's commit at factor " << fixed(c.factors.front(), 0)
            << ", the least tessellation): " << fixed(setupS / firstCommit, 2) << "x.\n\n";
    }
}

} // namespace dispmap::figures
