// `dispmap bench`: the seams table (seams_table.h).
#include "seams_table.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dispmap/io/mesh_writers.h"
#include "dispmap/io/png.h"
#include "dispmap/scene/surface.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/seams.h"
#include "dispmap/vulkan/renderer.h"
#include "figures.h"

namespace dispmap::figures {

namespace {

/// One shape class of the table: a control mesh (written to a scratch OBJ for the renderer),
/// its displacement, and whether its rule is the sharp one (points in the fade band) or the
/// end-cap one (points in the end-cap rings) for the "where it applies" timing.
struct SeamCase {
    std::string name;
    MeshDescription mesh;
    std::string height; ///< a height image (the mesh has UVs), else the waves
    double amplitude;   ///< of D, in units of the mesh's bounding-box diagonal
    bool sharpRule;
};

double extentOf(const MeshDescription& d) {
    glm::dvec3 lo(1e300), hi(-1e300);
    for (const glm::dvec3& p : d.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    return glm::length(hi - lo);
}

void sharpenEdges(MeshDescription& d, const std::vector<std::pair<int, int>>& edges) {
    for (auto [a, b] : edges) {
        d.creaseVertexPairs.push_back(a);
        d.creaseVertexPairs.push_back(b);
        d.creaseWeights.push_back(10.0f);
    }
}

std::vector<std::pair<int, int>> interiorEdges(const MeshDescription& d, int every) {
    const ControlMesh m{MeshDescription(d)};
    const Far::TopologyLevel& L = m.base();
    std::vector<std::pair<int, int>> out;
    for (int e = 0; e < L.GetNumEdges(); ++e)
        if (!L.IsEdgeBoundary(e) && e % every == 0) out.emplace_back(L.GetEdgeVertices(e)[0], L.GetEdgeVertices(e)[1]);
    return out;
}

/// The OBJ text of a description, tags included (the renderer reads meshes from files).
std::string objText(const MeshDescription& d) {
    std::ostringstream s;
    s.precision(17);
    for (const glm::dvec3& p : d.positions) s << "v " << p.x << " " << p.y << " " << p.z << "\n";
    for (const glm::dvec2& t : d.uvs) s << "vt " << t.x << " " << t.y << "\n";
    std::size_t at = 0;
    for (int n : d.faceSizes) {
        s << "f";
        for (int j = 0; j < n; ++j, ++at) {
            s << " " << d.faceVertices[at] + 1;
            if (!d.faceUVs.empty()) s << "/" << d.faceUVs[at] + 1;
        }
        s << "\n";
    }
    for (std::size_t i = 0; i < d.creaseWeights.size(); ++i)
        s << "t crease 2/1/0 " << d.creaseVertexPairs[2 * i] << " " << d.creaseVertexPairs[2 * i + 1] << " " << d.creaseWeights[i] << "\n";
    for (std::size_t i = 0; i < d.cornerWeights.size(); ++i) s << "t corner 1/1/0 " << d.cornerVertices[i] << " " << d.cornerWeights[i] << "\n";
    return s.str();
}

std::vector<SeamCase> seamCases() {
    const std::string data = DISPMAP_EXAMPLE_DATA;
    auto load = [&](const std::string& file) { return ControlMesh::fromObjFile(data + "/" + file).description(); };
    std::vector<SeamCase> cases;
    {
        MeshDescription cube = load("catmark_cube.obj");
        sharpenEdges(cube, interiorEdges(cube, 1));
        cases.push_back({"creases: cube, every edge sharp", cube, "", 0.03, true});
    }
    {
        MeshDescription cube = load("catmark_cube.obj");
        for (int v = 0; v < static_cast<int>(cube.positions.size()); ++v) {
            cube.cornerVertices.push_back(v);
            cube.cornerWeights.push_back(10.0f);
        }
        cases.push_back({"corners: cube, 8 sharp corners", cube, "", 0.03, true});
    }
    {
        // A crease of three edges along the torus's outer equator: two darts, two crease vertices.
        MeshDescription torus = builtin::torusMesh().description();
        sharpenEdges(torus, {{0, 1}, {1, 2}, {2, 3}});
        cases.push_back({"darts: torus, a 3-edge crease", torus, "", 0.03, true});
    }
    {
        MeshDescription spot = load("spot_control_mesh.obj");
        sharpenEdges(spot, interiorEdges(spot, 3));
        cases.push_back({"creases: spot, a third of its edges", spot, data + "/skimage_brick.png", 0.03, true});
    }
    cases.push_back({"EV 3, 5, 6: spot, brick image", load("spot_control_mesh.obj"), data + "/skimage_brick.png", 0.03, false});
    cases.push_back({"pole: valence 8 (pole8)", load("catmark_pole8.obj"), "", 0.03, false});
    for (int n : {3, 5, 10, 12})
        cases.push_back({"EV " + std::to_string(n) + ": closed fan", ControlMesh::fromObjText(builtin::fanObj(n, true), "fan").description(),
                         "", 0.03, false});
    return cases;
}

struct Measured {
    double gap = 0, jump = 0; ///< worst over all classes (jump: end caps and other edges; double)
    double jumpFloat = 0;
    double capEdge = 0; ///< across the end caps' outer edges inside faces (approximate, double)
    double nsAll = 0, nsRule = 0;
    double gpuMs = 0;
};

std::string fmt(double x, const char* f) {
    char b[32];
    std::snprintf(b, sizeof b, f, x);
    return b;
}

} // namespace

void printSeamsTable(std::ostream& out, const std::string& csvPath, const std::string& device) {
    vulkan::DeviceOptions dopt;
    dopt.device = device;
    vulkan::Context ctx(dopt);
    CsvOut csv(csvPath, "class,gap_before,jump_before,gap_after,jump_after,jump_after_float,cap_edge_after,ns_before,ns_after,ns_rule_before,"
                        "ns_rule_after,gpu_ms_before,gpu_ms_after");
    out << "Seams: f and its normal from both faces of every edge (surface/seams.h: 17 dyadic + 4 random points per edge, and\n"
        << "9 more in each end-cap ring), D of " << 3 << "% of the mesh size, k = 4, approximate normals, double (float: the\n"
        << "jump in float). Gap: |f_a - f_b| / mesh size; jump: the normals' angle (rad), on smooth edges (at sharp ones the\n"
        << "normal is meant to jump). before = the rules off (sharpBand 0, endCapNormals false), after = the defaults.\n"
        << "cap edge: after, the normal's jump across the end caps' outer edges inside faces (1e-9 either side).\n"
        << "ns/eval: DisplacedSurface::evaluate<float>, approximate, one thread, the fastest of 5 turns; all = uniform random\n"
        << "points, rule = points where the rule works (faces with sharp features, the end-cap rings). GPU: the fastest of 3\n"
        << "medians of 5 frames, 256 x 192,\n"
        << "uniform factor 16, on " << ctx.deviceName() << (ctx.isSoftware() ? " (a CPU device: GPU time is CPU time)" : "") << ".\n";
    out << std::left << std::setw(36) << "class" << std::right << std::setw(10) << "gap" << std::setw(9) << "jump" << std::setw(10)
        << "gap" << std::setw(9) << "jump" << std::setw(9) << "float" << std::setw(10) << "cap edge" << std::setw(13) << "ns/eval all" << std::setw(13) << "ns/eval rule"
        << std::setw(14) << "GPU ms" << "\n";
    out << std::left << std::setw(36) << "" << std::right << std::setw(19) << "before" << std::setw(38) << "after"
        << std::setw(13) << "before/after" << std::setw(13) << "before/after" << std::setw(14) << "before/after" << "\n";
    const std::filesystem::path scratch = std::filesystem::temp_directory_path();
    int index = 0;
    for (SeamCase& c : seamCases()) {
        const double size = extentOf(c.mesh);
        Scene scene = defaultScene();
        scene.width = 256;
        scene.height = 192;
        scene.mesh = (scratch / ("dispmap_seams_" + std::to_string(index++) + ".obj")).string();
        detail::writeFileAtomically(scene.mesh, [&] {
            const std::string t = objText(c.mesh);
            return std::vector<unsigned char>(t.begin(), t.end());
        }(), "mesh file");
        scene.displacement.height = c.height;
        scene.displacement.wrap = true;
        scene.displacement.scale = c.amplitude * size; // the waves: |D| <= scale; an image: D = scale h
        scene.displacement.k = 4;
        scene.effects.tessValue = 16;
        glm::dvec3 lo(1e300), hi(-1e300);
        for (const glm::dvec3& p : c.mesh.positions) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        scene.camera.target = 0.5 * (lo + hi);
        scene.camera.eye = scene.camera.target + glm::dvec3(2.6, 2.0, 3.4) * (0.42 * size);
        SceneSurface s(scene);
        std::remove(scene.mesh.c_str());

        // Points for the timing: uniform ones, and ones where the rule works.
        std::mt19937 rng(5);
        std::uniform_real_distribution<double> uni(0.0, 1.0);
        std::vector<glm::dvec3> all, rule;
        const double ring = std::ldexp(1.0, -s.base.options().isolationLevel);
        while (all.size() < 20000) {
            const int f = static_cast<int>(rng() % static_cast<unsigned>(s.base.faceCount()));
            if (!s.base.isHole(f)) all.emplace_back(f, uni(rng), uni(rng));
        }
        for (int tries = 0; rule.size() < 20000 && tries < 2000000; ++tries) {
            const int f = static_cast<int>(rng() % static_cast<unsigned>(s.base.faceCount()));
            if (s.base.isHole(f)) continue;
            const int c0 = static_cast<int>(rng() % 4);
            const glm::dvec2 corner = TileTopology::cornerUV(c0);
            if (c.sharpRule) {
                if (s.base.sharpMask(f) == 0) continue;
                const glm::dvec2 uv(uni(rng), uni(rng));
                rule.emplace_back(f, uv.x, uv.y); // faces with sharp features: the band covers most of them
            } else {
                if (!s.base.isExtraordinaryCorner(f, c0)) continue;
                const glm::dvec2 uv = corner + (glm::dvec2(0.5) - corner) * (2.0 * ring * glm::dvec2(uni(rng), uni(rng)));
                rule.emplace_back(f, uv.x, uv.y);
            }
        }
        Measured m[2];
        std::unique_ptr<DisplacedSurface> ds[2];
        std::unique_ptr<vulkan::SurfaceRenderer> renderer[2];
        for (int after = 0; after < 2; ++after) {
            DisplacedSurfaceOptions o;
            if (!after) {
                o.sharpBand = 0;
                o.endCapNormals = false;
            }
            ds[after] = std::make_unique<DisplacedSurface>(s.base, s.tiles, o);
            const SeamReport d = measureSeams<double>(*ds[after]), f = measureSeams<float>(*ds[after]);
            m[after].gap = std::max({d.sharp.positionGap, d.endCap.positionGap, d.other.positionGap});
            m[after].jump = std::max(d.endCap.normalJump, d.other.normalJump);
            m[after].jumpFloat = std::max(f.endCap.normalJump, f.other.normalJump);
            m[after].capEdge = d.endCapBoundary.normalJump;
            renderer[after] = std::make_unique<vulkan::SurfaceRenderer>(ctx, scene, *ds[after]);
            m[after].nsAll = m[after].nsRule = m[after].gpuMs = 1e300;
        }
        // Before and after in turns, the fastest of five: the machine is shared.
        auto time = [](const DisplacedSurface& surface, const std::vector<glm::dvec3>& pts) {
            if (pts.empty()) return 0.0;
            float sink = 0;
            const auto t0 = std::chrono::steady_clock::now();
            for (const glm::dvec3& p : pts)
                sink += surface.evaluate<float>(static_cast<int>(p.x), float(p.y), float(p.z), NormalMode::Approximate).normal.x;
            const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
            if (sink == 12345.0f) std::printf(" ");
            return ns / double(pts.size());
        };
        for (int round = 0; round < 5; ++round)
            for (int after = 0; after < 2; ++after) {
                m[after].nsAll = std::min(m[after].nsAll, time(*ds[after], all));
                m[after].nsRule = std::min(m[after].nsRule, time(*ds[after], rule));
                if (round < 3) m[after].gpuMs = std::min(m[after].gpuMs, renderer[after]->render(5, 1).stats.gpuMs);
            }
        out << std::left << std::setw(36) << c.name << std::right << std::setw(10) << fmt(m[0].gap, "%.1e") << std::setw(9)
            << fmt(m[0].jump, "%.1e") << std::setw(10) << fmt(m[1].gap, "%.1e") << std::setw(9) << fmt(m[1].jump, "%.1e")
            << std::setw(9) << fmt(m[1].jumpFloat, "%.1e") << std::setw(10) << fmt(m[1].capEdge, "%.1e") << std::setw(13)
            << (fmt(m[0].nsAll, "%.0f") + "/" + fmt(m[1].nsAll, "%.0f")) << std::setw(13)
            << (fmt(m[0].nsRule, "%.0f") + "/" + fmt(m[1].nsRule, "%.0f")) << std::setw(14)
            << (fmt(m[0].gpuMs, "%.1f") + "/" + fmt(m[1].gpuMs, "%.1f")) << "\n";
        csv << '"' << c.name << "\"," << m[0].gap << "," << m[0].jump << "," << m[1].gap << "," << m[1].jump << "," << m[1].jumpFloat
            << "," << m[1].capEdge << "," << m[0].nsAll << "," << m[1].nsAll << "," << m[0].nsRule << "," << m[1].nsRule << "," << m[0].gpuMs << ","
            << m[1].gpuMs << "\n";
    }
    csv.commit();
}

} // namespace dispmap::figures
