// The marcher parity runner: maps from one hard-case field, float ray sets (random, grazing,
// axis-aligned and on voxel walls, inside the solid, upward shadow rays), the CPU marchers of
// meso_march.h in float and shaders/meso/parity_meso.comp on the same rays.
#include "meso_parity.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include "dispmap/meso/march.h"
#include "dispmap/meso/solid.h"
#include "dispmap/vulkan/buffer.h"
#include "dispmap/vulkan/compute.h"
#include "dispmap/vulkan/context.h"
#include "dispmap/vulkan/meso_maps.h"
#include "parity_meso_spv.h"

namespace dispmap::parity {

MesoHeightField mesoParityField(int width, int height, int layers) {
    const double L = layers;
    std::vector<float> h(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
    for (int j = 0; j < height; ++j)
        for (int i = 0; i < width; ++i) {
            double v = 0.2 * L + 0.1 * L * std::sin(0.9 * i + 0.4 * j);
            if (i >= width - 3) v += 0.4 * L; // cliff
            if (j < 2) v = 0.0;               // floor
            if (i == width / 2 && j == height / 2) v = L; // spike to the top
            if (i == 2) v = L - 0.25;         // thin wall
            h[static_cast<std::size_t>(j * width + i)] = static_cast<float>(std::clamp(v, 0.0, L));
        }
    return mesoHeightField(width, height, layers, std::move(h));
}

MesoSolid mesoParitySolid() {
    std::vector<glm::dvec3> v;
    std::vector<std::array<int, 3>> t;
    appendUvSphere({4, 4, 3}, 3.0, 8, v, t);     // on the floor
    appendUvSphere({11, 10, 9}, 2.5, 8, v, t);   // floating: an overhang
    appendUvSphere({0.5, 9, 5}, 2.0, 6, v, t);   // across the side x = 0: its copy in the tile before
    appendUvSphere({8, 15, 12}, 2.5, 8, v, t);   // across the side y = 16
    // The tile: [0, 16]^2 in the mesh's units, the floor at z = 0.
    return mesoSolidFromMesh(v, t, 16, 16, 16, MesoSolidTile{{0, 0, 0}, 16.0});
}

namespace {

struct GpuRay {
    glm::vec4 o, d; // bent rays: the bend in o.w, the curve in d.w
};
static_assert(sizeof(GpuRay) == 32);

struct Push {
    vulkan::MesoGpuSize size;
    std::int32_t method, iterations;
    float eps;
    std::int32_t quadrics, exitRule, linear, binary;
    std::uint32_t count, rowStride;
};
static_assert(sizeof(Push) == 76);
constexpr std::int32_t kSolidMethod = 4; // parity_meso.comp's method of the solid's march
constexpr std::int32_t kBentMethod = 5; // and of the DDM along a bent ray
constexpr std::int32_t kBentHeightMethod = 6; // and of relief mapping / POM along a bent ray (POM: binary -1)
constexpr std::int32_t kBentSolidMethod = 7; // and of the solid's march along a bent ray
constexpr std::int32_t kBentDistanceMethod = 8; // and of the distance map along a bent ray

// Other devices (not strict): their sqrt and division need not round correctly (Vulkan allows
// a few ULP) and they may fuse, so a ray's decisions can go the other way where an intermediate
// lands at a threshold, and a different decision moves the hit by up to a step of the method.
// The bound is on the hit itself: within 1/16 voxel (Relief's final bracket is up to 1/43
// voxel at these slopes) for all but 0.1 % of the rays, the hit/miss answer the same. Measured
// on an NVIDIA H200 (docs/figures.md): no hit/miss flips, at most 1 ray of 16384 a row over
// 1/16 voxel (a bent chord cut elsewhere, a solid's shadow ray that ran out of iterations).
constexpr double kMesoDeviceVoxels = 1.0 / 16;
constexpr double kMesoDeviceShare = 0.001;

class RayGen {
  public:
    explicit RayGen(std::uint64_t seed) : rng_(seed) {}
    float uniform(double lo, double hi) { return static_cast<float>(std::uniform_real_distribution<double>(lo, hi)(rng_)); }
    int integer(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }
    // A unit float direction with the given z (before normalisation) and a random azimuth.
    glm::vec3 direction(float z) {
        const double az = std::uniform_real_distribution<double>(0, 6.283185307179586)(rng_);
        const double s = std::sqrt(std::max(0.0, 1.0 - double(z) * double(z)));
        return glm::normalize(glm::vec3(static_cast<float>(s * std::cos(az)), static_cast<float>(s * std::sin(az)), z));
    }

  private:
    std::mt19937_64 rng_;
};

float surfaceHeight(const MesoHeightField& f, float x, float y) {
    const int i = static_cast<int>(std::floor(x)), j = static_cast<int>(std::floor(y));
    return static_cast<float>(kern::dmBilerp(glm::dvec4(f.cell(i, j)), glm::dvec2(double(x) - double(i), double(y) - double(j))));
}

// View rays (d.z < 0): random from the top plane (over three periods, so the wrap is read),
// grazing (|d.z| 0.01 .. 0.05), on voxel walls and grid points with axis-aligned, diagonal and
// vertical directions, starting inside the solid, and starting in the air below the top.
std::vector<GpuRay> viewRays(const MesoHeightField& f, std::size_t n, RayGen& g) {
    const double W = f.width, H = f.height;
    const float L = float(f.layers);
    std::vector<GpuRay> rays;
    rays.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        GpuRay r{};
        const std::size_t kind = i % 10;
        glm::vec3 o(g.uniform(-W, 2.0 * W), g.uniform(-H, 2.0 * H), L), d;
        if (kind < 4) {
            d = g.direction(-g.uniform(0.05, 1.0));
        } else if (kind < 6) {
            d = g.direction(-g.uniform(0.01, 0.05));
        } else if (kind == 6) {
            o.x = float(g.integer(-f.width, 2 * f.width));
            if (i % 20 < 10) o.y = float(g.integer(-f.height, 2 * f.height));
            const float z = -g.uniform(0.01, 1.0);
            const float s = std::sqrt(1.0f - z * z);
            switch (g.integer(0, 5)) {
            case 0: d = glm::vec3(0, 0, -1); break;
            case 1: d = glm::normalize(glm::vec3(s, 0, z)); break;
            case 2: d = glm::normalize(glm::vec3(0, -s, z)); break;
            case 3: d = glm::normalize(glm::vec3(-s, s, z)); break;
            case 4: d = glm::normalize(glm::vec3(1, 1, -1)); break;
            default: d = glm::normalize(glm::vec3(-s, 0, z)); break;
            }
        } else if (kind < 9) {
            o.z = surfaceHeight(f, o.x, o.y) * g.uniform(0.0, 1.0); // inside the solid (or on the floor)
            d = g.direction(-g.uniform(0.01, 1.0));
        } else {
            o.z = L - g.uniform(0.0, 1.0);
            d = g.direction(-g.uniform(0.01, 1.0));
        }
        r.o = glm::vec4(o, 0.0f);
        r.d = glm::vec4(d, 0.0f);
        rays.push_back(r);
    }
    return rays;
}

// View rays from the top, bent by a curved base (o.w: the bend, kern::dmShellBend): convex and
// concave, weak and strong (1 to 16 chords), grazing and steep, and an eighth of them straight
// (bend 0: the straight march itself).
std::vector<GpuRay> bentRays(const MesoHeightField& f, std::size_t n, RayGen& g) {
    const double W = f.width, H = f.height;
    std::vector<GpuRay> rays;
    rays.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        GpuRay r{};
        const glm::vec3 o(g.uniform(-W, 2.0 * W), g.uniform(-H, 2.0 * H), float(f.layers));
        const glm::vec3 d = g.direction(-(i % 3 == 0 ? g.uniform(0.01, 0.1) : g.uniform(0.1, 1.0)));
        const float bend = i % 8 == 0 ? 0.0f : (i % 2 == 0 ? -1.0f : 1.0f) * std::exp(g.uniform(-9.0, -1.0));
        // Every other ray's depth follows a convex base's curvature (MesoBend::curve), up to the
        // renderer's limit (half the slab's depth: kern::dmShellLimit).
        const float curve = i % 2 == 1 ? -g.uniform(0.0, 0.5) / static_cast<float>(f.layers) : 0.0f;
        r.o = glm::vec4(o, bend);
        r.d = glm::vec4(d, curve);
        rays.push_back(r);
    }
    return rays;
}

// Shadow rays (d.z > 0) from on or just above the surface, some grazing, some from the air.
std::vector<GpuRay> shadowRays(const MesoHeightField& f, std::size_t n, RayGen& g) {
    const double W = f.width, H = f.height;
    const float L = float(f.layers);
    std::vector<GpuRay> rays;
    rays.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        GpuRay r{};
        glm::vec3 o(g.uniform(0.0, W), g.uniform(0.0, H), 0.0f);
        const float h = surfaceHeight(f, o.x, o.y);
        o.z = i % 4 == 3 ? g.uniform(h, L) : std::min(L, h + (i % 4 == 0 ? 0.0f : g.uniform(0.0, 0.05)));
        const glm::vec3 d = g.direction(i % 3 == 0 ? g.uniform(0.01, 0.05) : g.uniform(0.05, 1.0));
        r.o = glm::vec4(o, 0.0f);
        r.d = glm::vec4(d, 0.0f);
        rays.push_back(r);
    }
    return rays;
}

// Rays through the solid: view rays (d.z < 0) from the top over three periods, grazing, from
// grid points along axes and diagonals, from anywhere in the slab (inside the beads too);
// shadow rays (d.z > 0) from anywhere in the slab, a third grazing.
std::vector<GpuRay> solidRays(const MesoSolid& s, std::size_t n, RayGen& g, bool up) {
    const double W = s.width, H = s.height, L = s.layers;
    std::vector<GpuRay> rays;
    rays.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        const std::size_t kind = i % 10;
        glm::vec3 o(g.uniform(-W, 2.0 * W), g.uniform(-H, 2.0 * H), float(L)), d;
        if (up) {
            o.z = g.uniform(0.0, L);
            d = g.direction(i % 3 == 0 ? g.uniform(0.01, 0.05) : g.uniform(0.05, 1.0));
        } else if (kind < 4) {
            d = g.direction(-g.uniform(0.05, 1.0));
        } else if (kind < 6) {
            d = g.direction(-g.uniform(0.01, 0.05));
        } else if (kind == 6) {
            o = glm::vec3(float(g.integer(-s.width, 2 * s.width)), float(g.integer(-s.height, 2 * s.height)), float(g.integer(1, s.layers)));
            switch (g.integer(0, 3)) {
            case 0: d = glm::vec3(0, 0, -1); break;
            case 1: d = glm::normalize(glm::vec3(1, 0, -0.25f)); break;
            case 2: d = glm::normalize(glm::vec3(0, -1, -0.5f)); break;
            default: d = glm::normalize(glm::vec3(1, 1, -1)); break;
            }
        } else {
            o.z = g.uniform(0.0, L);
            d = g.direction(-g.uniform(0.01, 1.0));
        }
        rays.push_back(GpuRay{glm::vec4(o, 0.0f), glm::vec4(d, 0.0f)});
    }
    return rays;
}

enum class Maps { Cones, Isotropic, Solid, SolidIsotropic };

struct Row {
    const char* name;
    Maps maps; // isotropic DDM or 4 x 1 + shadow cones, of the field or of the solid
    MesoTechnique tq;
    int rays; // 0 view, 1 shadow, 2 half and half, 3 bent view rays (marchMesoBent)
};

MesoTechnique technique(MesoMethod m, int iterations, double eps, bool quadrics, int exitRule) {
    MesoTechnique t;
    t.method = m;
    t.iterations = iterations;
    t.eps = eps;
    t.quadrics = quadrics;
    t.exitRule = exitRule;
    return t;
}

std::string vec(const glm::vec3& v) {
    std::ostringstream s;
    s << std::setprecision(9) << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return s.str();
}

} // namespace

std::vector<KernelResult> runMeso(vulkan::Context& ctx, const Options& opt) {
    const MesoMethod DM = MesoMethod::DistanceMap, DDM = MesoMethod::Ddm;
    MesoTechnique relief = technique(MesoMethod::Relief, 0, -1, false, 1), pom = technique(MesoMethod::Pom, 0, -1, false, 1);
    relief.linear = 32;
    relief.binary = 6;
    pom.linear = 32;
    const Maps C = Maps::Cones, I = Maps::Isotropic, S = Maps::Solid, SI = Maps::SolidIsotropic;
    const Row rows[] = {
        {"march DistanceMap fixed 32", C, technique(DM, 32, -1, false, 1), 0},
        {"march DistanceMap eps 0.01 (cap 64)", C, technique(DM, 64, 0.01, false, 1), 0},
        {"march DistanceMap eps 0.01 bent rays", C, technique(DM, 64, 0.01, false, 1), 3},
        {"march Ddm 4x1 quadrics exit(v)+d", C, technique(DDM, 128, -1, true, 1), 0},
        {"march Ddm 4x1 quadrics t+d", C, technique(DDM, 128, -1, true, 0), 0},
        {"march Ddm 4x1 no quadrics exit(v)+d", C, technique(DDM, 128, -1, false, 1), 0},
        {"march Ddm 4x1 no quadrics t+d", C, technique(DDM, 128, -1, false, 0), 0},
        {"march Ddm 4x1+shadow shadow rays", C, technique(DDM, 128, -1, true, 1), 1},
        {"march Ddm 4x1+shadow shadow rays t+d", C, technique(DDM, 128, -1, false, 0), 1},
        {"march Ddm isotropic quadrics exit(v)+d", I, technique(DDM, 128, -1, true, 1), 2},
        {"march Ddm isotropic no quadrics t+d", I, technique(DDM, 128, -1, false, 0), 2},
        {"march Ddm 4x1 quadrics bent rays", C, technique(DDM, 128, kMesoChordError, true, 1), 3},
        {"march Ddm 4x1 no quadrics bent rays t+d", C, technique(DDM, 128, kMesoChordError, false, 0), 3},
        {"march Relief 32 + 6", C, relief, 0},
        {"march POM 32", C, pom, 0},
        {"march Relief 32 + 6 bent rays", C, relief, 3},
        {"march POM 32 bent rays", C, pom, 3},
        {"march Solid 4x1 exit(v)+d", S, technique(DDM, 256, -1, false, 1), 0},
        {"march Solid 4x1 t+d", S, technique(DDM, 256, -1, false, 0), 0},
        {"march Solid 4x1+shadow shadow", S, technique(DDM, 256, -1, false, 1), 1},
        {"march Solid 4x1 bent rays", S, technique(DDM, 256, kMesoChordError, false, 1), 3},
        {"march Solid isotropic exit(v)+d", SI, technique(DDM, 256, -1, false, 1), 2},
    };
    std::vector<const Row*> selected;
    for (const Row& r : rows)
        if (opt.filter.empty() || std::string(r.name).find(opt.filter) != std::string::npos) selected.push_back(&r);
    if (selected.empty()) return {};
    const bool strict = strictFor(ctx, opt);
    const std::size_t n = std::max<std::size_t>(opt.mesoRays, 64);
    const auto needs = [&](Maps m) { return std::any_of(selected.begin(), selected.end(), [&](const Row* r) { return r->maps == m; }); };

    // 16 x 16 x 16 voxels: every hard case, blocks of 4 (a mix of atlas and minimum blocks);
    // the solid: four beads, one on the floor, one at the tile's edge.
    const MesoHeightField field = mesoParityField(16, 16, 16);
    MesoMapOptions cones;
    cones.cones = ConeSet{4, 1, true, false};
    MesoMapOptions iso;
    iso.cones = ConeSet::all();
    MesoMapOptions solidOptions = cones;
    solidOptions.distance = false;
    MesoMapOptions solidIso = iso;
    solidIso.distance = false;
    const bool anySolid = needs(S) || needs(SI);
    const MesoSolid solid = anySolid ? mesoParitySolid() : MesoSolid{};

    RayGen g(opt.seed ^ 0x6d65736fULL);
    const std::vector<GpuRay> view = viewRays(field, n, g), shadow = shadowRays(field, n, g), bent = bentRays(field, n, g);
    const auto half = [&](const std::vector<GpuRay>& a, const std::vector<GpuRay>& b) {
        std::vector<GpuRay> m(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(n / 2));
        m.insert(m.end(), b.begin(), b.begin() + static_cast<std::ptrdiff_t>(n - n / 2));
        return m;
    };
    const std::vector<GpuRay> mixed = half(view, shadow);
    std::vector<GpuRay> solidView, solidShadow, solidMixed;
    if (anySolid) {
        solidView = solidRays(solid, n, g, false);
        solidShadow = solidRays(solid, n, g, true);
        solidMixed = half(solidView, solidShadow);
    }

    vulkan::ComputePipeline pipe(ctx, std::span<const std::uint32_t>(parity_meso_spv, sizeof(parity_meso_spv) / 4), 9, sizeof(Push));
    vulkan::Buffer rayBuf(ctx, n * sizeof(GpuRay)), outBuf(ctx, n * sizeof(glm::uvec4));
    std::vector<KernelResult> results;
    for (const Maps kind : {C, I, S, SI}) {
        if (!needs(kind)) continue;
        const bool isSolid = kind == S || kind == SI;
        const MesoMaps maps = isSolid ? buildMesoSolidMaps(solid, kind == S ? solidOptions : solidIso)
                                      : buildMesoMaps(field, kind == C ? cones : iso);
        const vulkan::MesoBuffers gpuMaps = vulkan::uploadMesoMaps(ctx, maps);
        for (const Row* row : selected) {
            if (row->maps != kind) continue;
            // (The solid has the field's 16 layers: the bent rays enter at its top too.)
            const std::vector<GpuRay>& rays = row->rays == 3 ? bent
                                              : isSolid      ? (row->rays == 0 ? solidView : row->rays == 1 ? solidShadow : solidMixed)
                                                             : (row->rays == 0 ? view : row->rays == 1 ? shadow : mixed);
            rayBuf.upload(rays.data(), rays.size() * sizeof(GpuRay));
            const auto count = static_cast<std::uint32_t>(rays.size());
            const std::uint32_t groupsX = std::min<std::uint32_t>((count + 63) / 64, 32768);
            const std::uint32_t groupsY = (count + groupsX * 64 - 1) / (groupsX * 64);
            const MesoTechnique& tq = row->tq;
            const Push push{vulkan::mesoGpuSize(maps),
                            row->rays != 3     ? (isSolid ? kSolidMethod : static_cast<std::int32_t>(tq.method))
                            : isSolid          ? kBentSolidMethod
                            : tq.method == DDM ? kBentMethod
                            : tq.method == DM  ? kBentDistanceMethod
                                               : kBentHeightMethod,
                            tq.iterations,
                            static_cast<float>(tq.eps),
                            tq.quadrics ? 1 : 0,
                            tq.exitRule,
                            tq.linear,
                            tq.method == MesoMethod::Pom ? -1 : tq.binary,
                            count,
                            groupsX * 64};
            const auto mb = gpuMaps.all();
            const vulkan::Buffer* bufs[] = {mb[0], mb[1], mb[2], mb[3], mb[4], &rayBuf, &outBuf, mb[5], mb[6]};
            KernelResult res;
            res.kernel = row->name;
            res.precision = "float";
            res.contract = isSolid && row->rays != 3 ? "march: div" : "march: sqrt, div"; // a bent ray: chords (sqrt)
            // Strict: bit-exact decisions and t (a zero t by value). Else |t| in voxels, see kMesoDeviceVoxels.
            res.unit = strict ? (isSolid ? "t ULP max(|t|,1); hit,n,tri" : "t: ULP max(|t|,1); hit, n") : "|t| voxels; 0.1% over";
            res.bound = strict ? 0.0 : kMesoDeviceVoxels;
            res.allowedOver = strict ? 0.0 : kMesoDeviceShare;
            res.inputs = rays.size();
            res.gpuSeconds = ctx.dispatch(pipe, bufs, glm::uvec3(groupsX, groupsY, 1), &push, sizeof push);
            std::vector<glm::uvec4> gpu(rays.size());
            outBuf.download(gpu.data(), gpu.size() * sizeof(glm::uvec4));
            double sum = 0;
            std::size_t flips = 0;
            std::vector<std::pair<double, std::size_t>> spread{{1e-4, 0}, {1.0 / 64, 0}, {1.0 / 16, 0}, {0.25, 0}};
            for (std::size_t i = 0; i < rays.size(); ++i) {
                const glm::vec3 o(rays[i].o), d(rays[i].d);
                MesoHit cpu;
                int triangle = -1;
                if (isSolid) {
                    const MesoSolidHit h = row->rays == 3 ? marchDdmSolidBent<float>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.solid, glm::dvec3(o),
                                                                                     glm::dvec3(d), MesoBend(rays[i].o.w, rays[i].d.w), tq.iterations,
                                                                                     tq.exitRule)
                                                          : marchDdmSolid<float>(CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.solid, glm::dvec3(o),
                                                                                 glm::dvec3(d), tq.iterations, tq.exitRule);
                    cpu = h;
                    triangle = h.triangle;
                } else if (row->rays == 3) {
                    cpu = marchMesoBent<float>(maps, tq, glm::dvec3(o), glm::dvec3(d), MesoBend(rays[i].o.w, rays[i].d.w));
                } else {
                    cpu = marchMeso<float>(maps, tq, glm::dvec3(o), glm::dvec3(d));
                }
                const auto tc = static_cast<float>(cpu.t);
                float tg;
                std::memcpy(&tg, &gpu[i].y, sizeof tg);
                const bool sameDecision = (gpu[i].x != 0) == cpu.hit && static_cast<int>(gpu[i].z) == cpu.iterations &&
                                          static_cast<int>(gpu[i].w) - 1 == triangle;
                // A zero t is compared by value: a ray starting on the floor z = 0 gets
                // dmPlaneHit = (0 - 0) / d.z = -0 in C++, and Mesa folds 0 - x into -x (+0 then),
                // a signed-zero rewrite NoContraction does not stop. The hit point is the same.
                const bool same = sameDecision && (std::memcmp(&tc, &tg, sizeof tc) == 0 || (tc == 0.0f && tg == 0.0f));
                double err = 0;
                if (!strict) {
                    // The distance of the hits along the ray (voxel-space rays are unit vectors);
                    // a miss on both sides has no hit to compare (its t is where the last step
                    // ended); a NaN is over every bound.
                    const bool gpuHit = gpu[i].x != 0;
                    flips += gpuHit != cpu.hit ? 1u : 0u;
                    err = gpuHit != cpu.hit ? std::numeric_limits<double>::infinity() : !cpu.hit ? 0.0 : std::abs(double(tc) - double(tg));
                    if (std::isnan(err)) err = std::numeric_limits<double>::infinity();
                    for (std::size_t k = 0; k < spread.size(); ++k) spread[k].second += !(err <= spread[k].first) ? 1u : 0u;
                    res.over += !(err <= res.bound) ? 1u : 0u; // a NaN t is over too
                } else if (!sameDecision) {
                    err = std::numeric_limits<double>::infinity(); // a different path: no ULP measure
                } else if (!same) {
                    const float scale = std::max(std::abs(tc), 1.0f);
                    const double ulp = double(std::nextafter(scale, std::numeric_limits<float>::infinity()) - scale);
                    err = std::abs(double(tc) - double(tg)) / ulp;
                    if (!std::isfinite(err)) err = std::numeric_limits<double>::infinity();
                }
                res.bitExact += same ? 1u : 0u;
                sum += std::isfinite(err) ? err : 0.0;
                if (err > res.maxUlp || (!same && res.worstInput.empty())) {
                    res.maxUlp = err;
                    std::ostringstream s;
                    s << std::setprecision(9) << "o=" << vec(o) << " d=" << vec(d) << " bend " << rays[i].o.w << " curve " << rays[i].d.w << ": cpu hit " << cpu.hit << " t " << tc << " n "
                      << cpu.iterations << " triangle " << triangle << ", gpu hit " << gpu[i].x << " t " << tg << " n " << gpu[i].z << " triangle "
                      << static_cast<int>(gpu[i].w) - 1 << std::hexfloat << " (" << tc << " vs " << tg << ")";
                    res.worstInput = s.str();
                }
            }
            res.meanUlp = sum / static_cast<double>(rays.size());
            if (!strict) {
                // How far the hits spread: shares of the rays over 1e-4 ... 1/4 voxel, and whose hit/miss differs.
                std::ostringstream s;
                s << std::setprecision(4);
                for (const auto& [limit, over] : spread) s << "> " << limit << ": " << 100.0 * double(over) / double(rays.size()) << "%, ";
                s << "hit/miss differs: " << 100.0 * double(flips) / double(rays.size()) << "%; worst " << res.worstInput;
                res.worstInput = s.str();
            }
            results.push_back(std::move(res));
        }
    }
    // In the order of the rows above.
    std::vector<KernelResult> ordered;
    for (const Row* r : selected)
        for (KernelResult& k : results)
            if (k.kernel == r->name) ordered.push_back(std::move(k));
    return ordered;
}

} // namespace dispmap::parity
