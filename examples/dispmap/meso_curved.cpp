// The curved-base table (examples/meso.h, printMesoCurvedTable): what Donnelly's locally planar
// march (§8.3.1: the ray in the tangent frame of the point where it enters, as MesoRenderer
// does on a FrameMesh) costs in accuracy on a curved base, against the exact curved shell, and
// the renderer's time on Spot beside the plane.
//
// The exact reference: a cylinder of radius R (the base surface) with the slab of depth delta
// below it, the shell map of the texture: a point at radius rho, angle theta and height z has
// texture coordinates (theta R / T, z / T) (tiles of T world units on the base) and voxel height
// (rho - (R - delta)) L / delta. A ray is solid where that height is at or below the bilinear
// height field H; inside the core (rho < R - delta) counts as the slab's floor, as the planar
// march's bottom rule. The reference walks the world ray in steps of 1/16 of the smallest voxel
// side in the shell and bisects the first crossing (60 halvings; a ridge thinner than a step
// could be stepped over, which would move the reference's hit later); a ray that leaves the
// shell through its top first is a miss.
// The planar march: the DDM 4x1 + quadric marcher (CPU, double) from the entry point's frame
// pS = T (-sin theta, cos theta, 0), pT = (0, 0, T), n = (cos theta, sin theta, 0).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <random>
#include <sstream>

#include "dispmap/kernels/meso.h"
#include "dispmap/kernels/meso_shade.h"
#include "dispmap/scene/meso.h"
#include "dispmap/vulkan/context.h"
#include "dispmap/vulkan/meso_renderer.h"
#include "meso.h"
#include "meso_scene_gpu.h"
#include "render.h"

namespace dispmap::figures {
namespace {

double percentileOf(std::vector<double> v, double p) {
    if (v.empty()) return std::nan("");
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

struct CurvedCell {
    std::vector<double> texelError; ///< |planar hit - exact hit| in texels of the texture, where both hit
    std::size_t rays = 0, falseHits = 0, falseMisses = 0;
    std::size_t cutFalseHits = 0, cutFalseMisses = 0; ///< the same with silhouettes (dmShellExit)
    std::vector<double> bentError;                      ///< the bent march's (marchMesoBent) hit against the exact one
    std::size_t bentFalseHits = 0, bentFalseMisses = 0;
};

// One height-field marcher (relief mapping, POM) on a cell's rays: planar and bent.
struct HeightCell {
    std::vector<double> planarError, bentError;
    std::size_t planarFalseHits = 0, planarFalseMisses = 0, bentFalseHits = 0, bentFalseMisses = 0;
    void add(const MesoHit& planar, const glm::dvec3& planarPoint, const MesoHit& bent, const glm::dvec3& bentPoint, bool exactHits,
             const glm::dvec3& exact) {
        planarFalseHits += planar.hit && !exactHits ? 1u : 0u;
        planarFalseMisses += !planar.hit && exactHits ? 1u : 0u;
        bentFalseHits += bent.hit && !exactHits ? 1u : 0u;
        bentFalseMisses += !bent.hit && exactHits ? 1u : 0u;
        if (planar.hit && exactHits) planarError.push_back(glm::length(planarPoint - exact));
        if (bent.hit && exactHits) bentError.push_back(glm::length(bentPoint - exact));
    }
};

// The cylinder's exact first hit of the ray P + t D (t >= 0, P on the outer surface), as the
// point's voxel coordinates (x, y along the texture, z the height), or false (left the shell).
bool exactHit(const MesoHeightField& f, double R, double delta, double T, const glm::dvec3& P, const glm::dvec3& D, glm::dvec3& hit) {
    const double W = f.width, H = f.height, L = f.layers;
    const auto voxel = [&](double t) {
        const glm::dvec3 X = P + D * t;
        const double rho = std::hypot(X.x, X.y);
        // The angle unwrapped from P's: the texture is not periodic around the cylinder.
        const double theta = std::atan2(P.y, P.x) + std::atan2(P.x * X.y - P.y * X.x, P.x * X.x + P.y * X.y);
        return glm::dvec3(theta * R / T * W, X.z / T * H, (rho - (R - delta)) * L / delta);
    };
    // g > 0 outside the solid; the core counts as solid.
    const auto g = [&](double t) {
        const glm::dvec3 v = voxel(t);
        if (v.z <= 0) return v.z;
        glm::dvec2 fr;
        const glm::ivec2 c = kern::dmHeightCell(glm::dvec2(v.x, v.y), fr);
        return v.z - kern::dmBilerp(glm::dvec4(f.cell(c.x, c.y)), fr);
    };
    // 1/16 of the smallest voxel side anywhere in the shell (texels shrink towards the core).
    const double step = std::min({T / W, T / H, delta / L}) * (1.0 - delta / R) / 16.0;
    double t0 = 0;
    for (int i = 1;; ++i) {
        if (i == 4000000) throw Error("meso --curved: the reference walk ran 4e6 steps without leaving the shell");
        const double t1 = i * step;
        if (voxel(t1).z > L) return false; // out through the top
        if (g(t1) <= 0) {
            double a = t0, b = t1;
            for (int k = 0; k < 60; ++k) (g(0.5 * (a + b)) > 0 ? a : b) = 0.5 * (a + b);
            hit = voxel(b);
            return true;
        }
        t0 = t1;
    }
}

} // namespace

void printMesoCurvedTable(std::ostream& out, const MesoTableArgs& args) {
    out << "Curved base: Donnelly's locally planar march (the ray in the frame where it enters) against the exact shell of a "
           "cylinder of radius R, the slab delta deep below it, tiles of T = 5 delta (the plane scenes' proportion); DDM 4x1 + "
           "quadrics on the grating (64 x 64 x 16), 400 rays a cell at random points and azimuths. Error: the distance between the "
           "planar and the exact hit in texels (x, y) and voxels (z), where both hit; false hits: the planar march hits where the "
           "exact ray leaves the shell (a silhouette the planar march fills in); with silhouettes "
           "(MesoRenderOptions::silhouettes): the same march, its hit dropped past the point where the ray leaves the shell "
           "modelled by the cylinder's second fundamental form and principal curvature (kern::dmShellExit: the cylinder's exact top), false hits and false misses (the exact ray "
           "hits, the cut march does not). Bent: the march along the ray bent by the same quadric (MesoRenderOptions::bentRays, "
           "marchMesoBent: chords of the curve the straight world ray is in the slab's own coordinates, its depth the cylinder's), its hit in those "
           "coordinates against the exact one.\n\n";
    const MesoHeightField field = mesoFunctionField("grating", 64, 16);
    // With shadow cones: the bent march's chords rise again where the cylinder curves away (the
    // view cones, and the straight march, are the same without them).
    MesoMapOptions mo = mesoMapOptionsFor(MesoTechnique{}, true, parseConeSet("4x1"));
    mo.distance = true; // Donnelly's map for the second table's distance-map columns
    const MesoMaps maps = buildMesoMaps(field, mo);
    MesoTechnique tq;
    tq.iterations = 1024;
    const double incidence[][2] = {{0.0, 30.0}, {30.0, 60.0}, {60.0, 80.0}};
    out << "| delta / R | incidence | error p50 | error p90 | false hits | false hits, silhouettes | false misses, silhouettes | "
           "bent: error p50 | bent: error p90 | bent: false hits | bent: false misses |\n"
           "|---|---|---|---|---|---|---|---|---|---|---|\n";
    // Relief mapping (32 steps + 6 bisections), POM (32 steps) and Donnelly's distance map (eps
    // 0.02, at most 64 steps) on the same rays, planar and bent (kern::dmMesoMarchHeightBent,
    // kern::dmMesoMarchDistanceBent): a second table.
    MesoTechnique relief, pom, distance;
    relief.method = MesoMethod::Relief;
    pom.method = MesoMethod::Pom;
    distance.method = MesoMethod::DistanceMap;
    distance.iterations = 64;
    distance.eps = 0.02;
    std::ostringstream heightRows;
    std::mt19937 gen(2026);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    for (const double ratio : {0.003, 0.01, 0.03, 0.1, 0.3}) {
        const double R = 1.0, delta = ratio * R, T = 5.0 * delta;
        const glm::dvec3 vpu(field.width, field.height, field.layers / delta);
        for (const auto& band : incidence) {
            CurvedCell cell;
            HeightCell reliefCell, pomCell, distanceCell;
            for (int r = 0; r < 400; ++r) {
                const double theta = 3.141592653589793 * (2.0 * u01(gen) - 1.0), z = 10.0 * T * u01(gen);
                const glm::dvec3 n(std::cos(theta), std::sin(theta), 0.0), tangent(-std::sin(theta), std::cos(theta), 0.0), axis(0, 0, 1);
                const glm::dvec3 P = n * R + axis * z;
                const double a = glm::radians(band[0] + (band[1] - band[0]) * u01(gen)), phi = 6.283185307179586 * u01(gen);
                const glm::dvec3 D = -n * std::cos(a) + (tangent * std::cos(phi) + axis * std::sin(phi)) * std::sin(a);
                ++cell.rays;
                // The planar march from P's frame.
                const glm::dvec3 pS = tangent * T, pT = axis * T;
                const glm::dvec3 tex(theta * R / T, z / T, 0.0);
                const glm::dvec3 o = kern::dmMesoEntry(tex, vpu, field.layers);
                const glm::dvec3 d = kern::dmTangentToVoxel(kern::dmFrameCoordinates(D, pS, pT, n), vpu);
                const MesoHit planar = marchMeso<double>(maps, tq, o, d);
                glm::dvec3 exact(0.0);
                const bool exactHits = exactHit(field, R, delta, T, P, D, exact);
                if (planar.hit && !exactHits) ++cell.falseHits;
                if (!planar.hit && exactHits) ++cell.falseMisses;
                // With silhouettes: the cylinder's second fundamental form in (s, t) is
                // (n . P_ss, n . P_st, n . P_tt) = (-T^2 / R, 0, 0), its most convex principal
                // curvature -1 / R (FrameVertex::shape).
                // As the renderer takes it (kern::dmShellLimit: unchanged up to delta / R = 0.5).
                const glm::dvec4 shape = kern::dmShellLimit(glm::dvec4(-T * T / R, 0.0, 0.0, -1.0 / R), vpu, double(field.layers), kShellCurvatureLimit);
                const double exitT = kern::dmShellExit(o, d, o, shape, vpu, double(field.layers));
                const bool cutHit = planar.hit && !(exitT >= 0 && planar.t > exitT);
                if (cutHit && !exactHits) ++cell.cutFalseHits;
                if (!cutHit && exactHits) ++cell.cutFalseMisses;
                // With bent rays: the same DDM march along the ray bent by the same quadric, its
                // depth the cylinder's (MesoBend's curve: kern::dmBentPoint).
                glm::dvec3 slab(0.0);
                const MesoBend bend(kern::dmShellBend(d, shape, vpu), kern::dmShellVoxels(shape, vpu).w);
                const MesoHit bent = marchMesoBent<double>(maps, tq, o, d, bend, &slab);
                if (bent.hit && !exactHits) ++cell.bentFalseHits;
                if (!bent.hit && exactHits) ++cell.bentFalseMisses;
                if (planar.hit && exactHits) {
                    cell.texelError.push_back(glm::length(planar.point(o, d) - exact));
                }
                if (bent.hit && exactHits) cell.bentError.push_back(glm::length(slab - exact));
                for (auto [tqh, hc] : {std::pair{&relief, &reliefCell}, std::pair{&pom, &pomCell}, std::pair{&distance, &distanceCell}}) {
                    const MesoHit hp = marchMeso<double>(maps, *tqh, o, d);
                    glm::dvec3 hs(0.0);
                    const MesoHit hb = marchMesoBent<double>(maps, *tqh, o, d, bend, &hs);
                    hc->add(hp, hp.point(o, d), hb, hs, exactHits, exact);
                }
            }
            heightRows << std::defaultfloat << std::setprecision(3) << "| " << ratio << " | " << band[0] << "–" << band[1] << "°";
            for (const HeightCell* hc : {&reliefCell, &pomCell, &distanceCell}) {
                const double n = static_cast<double>(cell.rays);
                heightRows << std::defaultfloat << std::setprecision(3) << " | " << percentileOf(hc->planarError, 0.5) << " / "
                           << percentileOf(hc->planarError, 0.9) << " | " << std::fixed << std::setprecision(1)
                           << 100.0 * static_cast<double>(hc->planarFalseHits) / n << " % / " << 100.0 * static_cast<double>(hc->planarFalseMisses) / n
                           << " % | " << std::defaultfloat << std::setprecision(3) << percentileOf(hc->bentError, 0.5) << " / "
                           << percentileOf(hc->bentError, 0.9) << " | " << std::fixed << std::setprecision(1)
                           << 100.0 * static_cast<double>(hc->bentFalseHits) / n << " % / " << 100.0 * static_cast<double>(hc->bentFalseMisses) / n << " %";
            }
            heightRows << " |\n";
            std::ostringstream row;
            row << std::setprecision(3) << "| " << ratio << " | " << band[0] << "–" << band[1] << "° | " << percentileOf(cell.texelError, 0.5)
                << " | " << percentileOf(cell.texelError, 0.9) << " | " << std::fixed << std::setprecision(1)
                << 100.0 * static_cast<double>(cell.falseHits) / static_cast<double>(cell.rays) << " %"
                << (cell.falseMisses ? " (" + std::to_string(cell.falseMisses) + " false misses)" : "") << " | "
                << 100.0 * static_cast<double>(cell.cutFalseHits) / static_cast<double>(cell.rays) << " % | "
                << 100.0 * static_cast<double>(cell.cutFalseMisses) / static_cast<double>(cell.rays) << " % | " << std::defaultfloat
                << std::setprecision(3) << percentileOf(cell.bentError, 0.5) << " | " << percentileOf(cell.bentError, 0.9) << " | " << std::fixed
                << std::setprecision(1) << 100.0 * static_cast<double>(cell.bentFalseHits) / static_cast<double>(cell.rays) << " % | "
                << 100.0 * static_cast<double>(cell.bentFalseMisses) / static_cast<double>(cell.rays) << " % |\n";
            out << row.str();
        }
    }
    out << "\nRelief mapping (32 linear steps + 6 bisections), POM (32 steps) and Donnelly's distance map (eps 0.02, at most 64 "
           "steps) on the same rays and field, planar (the ray in the entry's frame) and bent (kern::dmMesoMarchHeightBent: the "
           "linear search and its refinement on the bent ray itself; kern::dmMesoMarchDistanceBent: sphere tracing along it); error "
           "p50 / p90 as above, false hits / false misses against the exact shell:\n\n"
           "| delta / R | incidence | relief: error | relief: false hits / misses | relief bent: error | relief bent: false hits / misses "
           "| POM: error | POM: false hits / misses | POM bent: error | POM bent: false hits / misses "
           "| distance map: error | distance map: false hits / misses | distance map bent: error | distance map bent: false hits / misses |\n"
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
        << heightRows.str();

    // The renderer on a curved base beside the plane: the Spot scene of tests/data.
    if (!args.gpu) return;
    try {
        vulkan::DeviceOptions dopt;
        dopt.device = args.device;
        vulkan::Context ctx(dopt);
        const std::string path = args.dataDir + "/scenes/meso_spot_grating.json";
        const MesoSceneDesc s = parseMesoScene(loadSceneJson(path), path, args.dataDir + "/scenes");
        const MesoMaps m = buildMesoSceneMaps(s);
        const auto t0 = std::chrono::steady_clock::now();
        const std::shared_ptr<const FrameMesh> base = buildMesoSceneBase(s);
        const double baseS = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        vulkan::MesoRenderOptions o = mesoSceneRenderOptions(s);
        o.frames = args.gpuFrames;
        o.warmup = args.gpuWarmup;
        const auto stats = [&](const vulkan::MesoImage& im) {
            double it = 0, sit = 0;
            std::size_t covered = 0, hits = 0;
            for (std::size_t i = 0; i < im.covered.size(); ++i)
                if (im.covered[i]) {
                    it += im.iterations[i];
                    sit += im.shadowIterations[i];
                    ++covered;
                    hits += im.hit[i];
                }
            std::ostringstream r;
            r << std::fixed << std::setprecision(2) << im.gpuMs << " ms | " << covered << " | " << hits << " | "
              << it / static_cast<double>(std::max<std::size_t>(covered, 1)) << " | " << sit / static_cast<double>(std::max<std::size_t>(covered, 1));
            return r.str();
        };
        out << "\nThe renderer (" << ctx.deviceName() << ", " << o.width << " x " << o.height << ", DDM 4x1 + quadrics, shadows, median of "
            << o.frames << " frames after " << o.warmup << " untimed; covered: pixels the base covers, back faces included; iterations over them):\n\n"
            << "| base | GPU time | pixels covered | hits | view iterations (mean) | shadow iterations (mean) |\n|---|---|---|---|---|---|\n";
        // The plane beside it: the bricks scene's camera and light, the default checker.
        vulkan::MesoRenderOptions plane = o;
        plane.camera = vulkan::MesoCamera{};
        plane.camera.eye = {0.3, -1.1, 0.6};
        plane.lightDirection = {0.5, 0.2, 0.6};
        plane.depth = 0.05;
        plane.checkerVoxels = vulkan::MesoRenderOptions{}.checkerVoxels;
        out << "| the plane, tile 0.5 | " << stats(vulkan::renderMeso(ctx, m, plane)) << " |\n";
        o.base = base;
        out << "| Spot (" << base->triangleCount() << " triangles, built in " << std::fixed << std::setprecision(2) << baseS << " s) | "
            << stats(vulkan::renderMeso(ctx, m, o)) << " |\n";
        // The same with the base's curvature (FrameMeshOptions::shape): silhouettes, bent rays.
        MesoSceneDesc shaped = s;
        shaped.placement.shape = true;
        const auto t1 = std::chrono::steady_clock::now();
        o.base = buildMesoSceneBase(shaped);
        const double shapedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
        o.silhouettes = true;
        out << "| Spot, silhouettes (the base with its curvature built in " << std::setprecision(2) << shapedS << " s) | "
            << stats(vulkan::renderMeso(ctx, m, o)) << " |\n";
        o.silhouettes = false;
        o.bentRays = true;
        out << "| Spot, bent rays | " << stats(vulkan::renderMeso(ctx, m, o)) << " |\n";
        // Relief mapping and POM on the same base, planar and bent (the DDM still casts the shadows).
        for (const MesoMethod method : {MesoMethod::Relief, MesoMethod::Pom}) {
            o.technique = MesoTechnique{};
            o.technique.method = method;
            const std::string name = method == MesoMethod::Relief ? "relief 32 + 6" : "POM 32";
            o.bentRays = false;
            out << "| Spot, " << name << " | " << stats(vulkan::renderMeso(ctx, m, o)) << " |\n";
            o.bentRays = true;
            out << "| Spot, " << name << ", bent rays | " << stats(vulkan::renderMeso(ctx, m, o)) << " |\n";
        }
        // The distance map on the same base (its own maps: the scene's are the DDM's).
        {
            MesoSceneDesc ds = shaped;
            ds.technique.method = MesoMethod::DistanceMap;
            ds.technique.iterations = 64;
            ds.technique.eps = 0.02;
            const MesoMaps dm = buildMesoSceneMaps(ds);
            o.technique = ds.technique;
            o.bentRays = false;
            out << "| Spot, distance map eps 0.02 | " << stats(vulkan::renderMeso(ctx, dm, o)) << " |\n";
            o.bentRays = true;
            out << "| Spot, distance map eps 0.02, bent rays | " << stats(vulkan::renderMeso(ctx, dm, o)) << " |\n";
        }
        // A solid on Spot (the chain mail scene of tests/data, its own camera and light), straight and bent.
        {
            const std::string chain = args.dataDir + "/scenes/meso_spot_chainmail.json";
            MesoSceneDesc cs = parseMesoScene(loadSceneJson(chain), chain, args.dataDir + "/scenes");
            cs.bentRays = true; // its maps then carry the shadow cones a bent ray needs, and its base the curvature
            cs.placement.shape = true;
            const MesoMaps cm = buildMesoSceneMaps(cs);
            vulkan::MesoRenderOptions co = mesoSceneRenderOptions(cs);
            co.frames = args.gpuFrames;
            co.warmup = args.gpuWarmup;
            co.base = buildMesoSceneBase(cs);
            co.bentRays = false;
            out << "| Spot, chain mail (a solid; its scene) | " << stats(vulkan::renderMeso(ctx, cm, co)) << " |\n";
            co.bentRays = true;
            out << "| Spot, chain mail, bent rays | " << stats(vulkan::renderMeso(ctx, cm, co)) << " |\n";
        }
    } catch (const Error& e) {
        out << "\n(no renderer rows: " << e.what() << ")\n";
    }
}

} // namespace dispmap::figures
