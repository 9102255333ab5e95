// `dispmap render` and the renderer's tables (see render.h).
#include "render.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

#include "text_format.h"
#include "dispmap/io/png.h"
#include "dispmap/scene/surface.h"
#include "dispmap/scene/meso.h"
#include "dispmap/vulkan/meso_renderer.h"
#include "meso_scene_gpu.h"
#include "dispmap/vulkan/renderer.h"
#include "figures.h"

namespace dispmap::figures {

namespace {

std::unique_ptr<vulkan::Context> makeContext(const std::string& device, bool validation) {
    vulkan::DeviceOptions o;
    o.device = device;
    o.validation = validation;
    return std::make_unique<vulkan::Context>(o);
}

void writePng(const vulkan::RenderedImage& im, const std::string& path) {
    writeRgbaPng(path, im.width, im.height, im.rgba.data());
}


} // namespace

namespace {
// A mesostructure scene (meso_scene.h): the maps its effects need, the fragment-shader marcher;
// several mesostructures each on their material's triangles, in one pass.
int renderMesoCommand(const RenderArgs& a, const nlohmann::json& j) {
    const MesoSceneDesc s = parseMesoScene(j, a.scene, std::filesystem::path(a.scene).parent_path().string());
    MesoSceneGpu scene = buildMesoSceneGpu(s);
    scene.options.frames = a.frames;
    scene.options.warmup = a.warmup;
    const vulkan::MesoRenderOptions& o = scene.options;
    const std::vector<MesoSceneDesc>& descs = scene.descs;
    const std::vector<MesoMaps>& maps = scene.maps;
    const std::vector<vulkan::MesoPart>& parts = scene.parts;
    auto ctx = makeContext(a.device, a.validation);
    const vulkan::MesoImage im = vulkan::renderMeso(*ctx, parts, o);
    if (!a.output.empty()) writeRgbaPng(a.output, im.width, im.height, im.rgba.data());
    std::vector<double> iterations(parts.size(), 0.0);
    std::vector<std::size_t> covered(parts.size(), 0);
    for (std::size_t i = 0; i < im.iterations.size(); ++i)
        if (im.covered[i] && im.part[i] < parts.size()) {
            iterations[im.part[i]] += im.iterations[i];
            ++covered[im.part[i]];
        }
    const char* methods[] = {"distance map", "DDM", "relief", "POM"};
    const auto built = [](const MesoMaps& m) {
        std::string list;
        const auto add = [&](bool has, const std::string& what) {
            if (has) list += (list.empty() ? "" : ", ") + what;
        };
        add(!m.field.h.empty(), "heights");
        add(!m.distance.d.empty(), "distance map");
        add(!m.ddm.grid.empty(), "DDM");
        add(!m.quadrics.q.empty(), "quadrics");
        add(m.isSolid(), "triangle lists " + std::to_string(m.solid.bytes() >> 10) + " KiB");
        return list;
    };
    std::cout << "mesostructure scene '" << s.name << "' on " << ctx->deviceName()
              << (o.base ? "; on '" + s.base->mesh + "' (" + std::to_string(o.base->triangleCount()) + " triangles)" : "") << "\n";
    for (std::size_t i = 0; i < parts.size(); ++i) {
        const MesoSceneDesc& d = descs[i];
        const vulkan::MesoLook& l = parts[i].look;
        const MesoMaps& m = maps[i];
        std::cout << "  " << (parts.size() > 1 ? d.key + (d.material.empty() ? " (the other faces)" : " (material '" + d.material + "')") + ", " +
                                                     std::to_string(parts[i].triangles) + " triangles: "
                                               : std::string())
                  << (m.isSolid() ? "mesh " + std::to_string(m.solid.triangles.size()) + " triangles in " + std::to_string(m.solid.width) + " x " +
                                        std::to_string(m.solid.height) + " x " + std::to_string(m.solid.layers) + " voxels, " +
                                        fixed(100 * m.solid.solidShare(), 1) + " % solid: "
                                  : "")
                  << methods[static_cast<int>(d.technique.method)]
                  << (d.technique.method == MesoMethod::Ddm
                          ? (m.isSolid() ? " + triangles, cones " : d.technique.quadrics ? " + quadric, cones " : ", cones ") + d.cones.name()
                          : "")
                  << (d.shadows ? ", self-shadowing" : "")
                  << (l.albedo ? ", albedo " + std::to_string(l.albedo->width()) + " x " + std::to_string(l.albedo->height()) + (l.albedo->levels() > 1 ? " with mips" : "") : "")
                  << (l.normalMap ? ", normal map " + std::to_string(l.normalMap->width()) + " x " + std::to_string(l.normalMap->height()) + (d.normalsFromHeight ? " from the heights" : "") : "")
                  << "; maps built: " << built(m) << "; mean iterations "
                  << fixed(covered[i] ? iterations[i] / static_cast<double>(covered[i]) : 0.0, 2) << " over " << covered[i] << " pixels\n";
    }
    const auto cut = std::count(im.cut.begin(), im.cut.end(), std::uint8_t{1});
    std::cout << "  " << im.width << " x " << im.height << ": GPU time " << fixed(im.gpuMs, 3) << " ms (median of " << im.frames << " frames)"
              << (o.bentRays ? ", bent rays" : "")
              << (o.silhouettes && !o.bentRays ? ", silhouettes: " + std::to_string(cut) + " pixels whose march hit past the shell's exit (a miss)" : "")
              << (o.silhouettes || o.bentRays ? ", the slab meets itself at " + std::to_string(foldedCorners(*o.base, o.depth)) +
                                                    " corners (concave radius below its depth)"
                                              : "")
              << (a.output.empty() ? "" : ", wrote " + a.output) << "\n";
    int status = 0;
    for (const std::string& m : ctx->takeValidationMessages()) {
        std::cerr << "validation: " << m << "\n";
        status = 1;
    }
    return status;
}
} // namespace

int renderCommand(const RenderArgs& a) {
    // The options first: a scene can take seconds to build.
    if (a.warmup < 0 || a.warmup > kMaxRenderFrames)
        throw ArgumentError("--warmup " + std::to_string(a.warmup) + " is not in 0.." + std::to_string(kMaxRenderFrames));
    if (a.frames < 1 || a.frames > kMaxRenderFrames)
        throw ArgumentError("--frames " + std::to_string(a.frames) + " is not in 1.." + std::to_string(kMaxRenderFrames) +
                            " (each frame is drawn in full: the cap keeps a typo from running for hours)");
    if (a.facesPerDraw < 1 || a.facesPerDraw > kMaxFacesPerDraw)
        throw ArgumentError("--faces-per-draw " + std::to_string(a.facesPerDraw) + " is not in 1.." + std::to_string(kMaxFacesPerDraw) +
                            ": lavapipe runs each tessellated draw on one thread in a loop whose time grows faster than the "
                            "patches in it (docs/lavapipe.md); Spot at factor 64 took 3.4 s a frame at 16 faces per draw, 25 s at "
                            "32 and 62 s at 64");
    if (!a.output.empty()) detail::checkOutputPath(a.output, "RGBA image");
    Scene scene;
    if (!a.scene.empty()) {
        // One read and one parse (size and nesting limited, scene/scene.h) for both kinds.
        const nlohmann::json j = loadSceneJson(a.scene);
        if (isMesoScene(j)) return renderMesoCommand(a, j);
        scene = parseSceneDocument(j, a.scene, std::filesystem::path(a.scene).parent_path().string());
    } else {
        scene = defaultScene();
    }
    // Host time, stage by stage, beside the GPU time: what a large cage costs before and around
    // its frames.
    using Clock = std::chrono::steady_clock;
    auto msSince = [](Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); };
    auto t0 = Clock::now();
    SceneSurface s(scene);
    const double surfaceMs = msSince(t0);
    t0 = Clock::now();
    auto ctx = makeContext(a.device, a.validation);
    const double deviceMs = msSince(t0);
    if (ctx->isSoftware()) {
        // Frame time on a CPU device grows with the triangles (docs/lavapipe.md): refused when
        // one frame would take minutes. The count is the CPU tessellator's at the scene's
        // uniform factor, or at the maximum factor for the other methods (an upper bound).
        const SurfaceEffects& e = scene.effects;
        const double factor = e.tessMethod == TessMethod::Uniform ? std::min(e.tessValue, e.maxFactor) : e.maxFactor;
        TessellateOptions to;
        to.maxFactor = e.maxFactor;
        to.spacing = e.spacing;
        const std::uint64_t triangles =
            Tessellator(s.surface, uniformTessFactors(s.base, factor), to).estimate().triangles * (e.wireframe ? 2 : 1);
        if (triangles > kMaxSoftwareTrianglesPerFrame)
            throw ArgumentError("scene '" + scene.name + "': up to " + std::to_string(triangles) + " triangles per frame, more than the " +
                                std::to_string(kMaxSoftwareTrianglesPerFrame) + " a CPU device (" + ctx->deviceName() +
                                ", 0.4 to 1.5 million a second) draws in a minute or more: lower effects.tessellation.value or .max");
    }
    vulkan::RendererOptions o;
    o.facesPerDraw = a.facesPerDraw;
    t0 = Clock::now();
    vulkan::SurfaceRenderer r(*ctx, scene, s.surface, s.atlas ? &*s.atlas : nullptr, o);
    const double rendererMs = msSince(t0);
    t0 = Clock::now();
    const vulkan::RenderedImage im = r.render(a.frames, a.warmup);
    const double framesMs = msSince(t0);
    if (!a.output.empty()) writePng(im, a.output);
    const SurfaceEffects& e = scene.effects;
    std::cout << "scene '" << scene.name << "' on " << ctx->deviceName() << (ctx->isSoftware() ? " (a CPU device: GPU time is CPU time)" : "")
              << "\n  " << toString(e.technique) << ", normals " << (e.normals == NormalMode::Approximate ? "approximate" : e.normals == NormalMode::Accurate ? "accurate" : "auto")
              << ", LOD " << toString(e.lod) << ", factors " << toString(e.tessMethod) << " " << e.tessValue << " (max " << e.maxFactor
              << ", " << toString(e.spacing) << ")" << (e.wireframe ? ", wireframe" : "") << "\n"
              << "  " << im.width << " x " << im.height << ": GPU time " << fixed(im.stats.gpuMs, 3) << " ms (median of " << im.stats.frames
              << " frames), " << im.stats.patches << " patches, " << im.stats.triangles << " triangles, " << im.stats.tesInvocations << " evaluation shader invocations"
              << (a.output.empty() ? "" : ", wrote " + a.output) << "\n"
              << "  host: surface " << fixed(surfaceMs, 1) << " ms (base surface, tiles, DisplacedSurface), device " << fixed(deviceMs, 1)
              << " ms, renderer " << fixed(rendererMs, 1) << " ms (pipelines, uploads), frames " << fixed(framesMs, 1) << " ms wall for "
              << im.stats.frames + a.warmup << " (" << a.warmup << " untimed; GPU " << fixed(im.stats.gpuMs, 1) << " ms a frame)\n";
    int status = 0;
    for (const std::string& m : ctx->takeValidationMessages()) {
        std::cerr << "validation: " << m << "\n";
        status = 1;
    }
    return status;
}

namespace {
// The scene printRenderTable draws, its arguments checked.
Scene renderTableScene(const RenderTableArgs& a) {
    if (a.frames < 1 || a.frames > kMaxRenderFrames || a.warmup < 0 || a.warmup > kMaxRenderFrames)
        throw ArgumentError("--render-frames " + std::to_string(a.frames) + " / --render-warmup " + std::to_string(a.warmup) +
                            ": the timed frames must be in 1.." + std::to_string(kMaxRenderFrames) + " and the untimed ones in 0.." +
                            std::to_string(kMaxRenderFrames));
    if (a.scene.empty()) return defaultScene();
    const nlohmann::json j = loadSceneJson(a.scene);
    if (isMesoScene(j)) throw ArgumentError("--render-scene " + a.scene + ": a mesostructure scene; the renderer table needs a surface scene");
    Scene scene = parseSceneDocument(j, a.scene, std::filesystem::path(a.scene).parent_path().string());
    // What the rows vary is theirs to set: the technique (the reference is the displaced
    // surface), uniform factors up to 64 with the header's spacing, no wireframe.
    scene.effects.technique = Technique::Displaced;
    scene.effects.spacing = Spacing::FractionalEven;
    scene.effects.tessMethod = TessMethod::Uniform;
    scene.effects.maxFactor = 64;
    scene.effects.wireframe = false;
    return scene;
}
} // namespace

void checkRenderTableArgs(const RenderTableArgs& a) { static_cast<void>(renderTableScene(a)); }

void printRenderTable(std::ostream& out, const RenderTableArgs& a) {
    Scene scene = renderTableScene(a);
    SceneSurface s(scene);
    const BaselineAtlas& atlas = s.bake(scene);
    auto ctx = makeContext(a.device, false);
    const int factor = 32;

    // Reference: accurate normals, no mips, the highest factor.
    Scene refScene = scene;
    refScene.effects.normals = NormalMode::Accurate;
    refScene.effects.lod = MipSelection::Off;
    refScene.effects.tessValue = 64;
    const vulkan::RenderedImage ref = vulkan::SurfaceRenderer(*ctx, refScene, s.surface).render(1, 1);
    if (!a.imageDir.empty()) {
        std::filesystem::create_directories(a.imageDir);
        writePng(ref, a.imageDir + "/reference.png");
    }

    struct Row {
        std::string name, file;
        Technique technique;
        NormalMode normals;
        MipSelection lod;
        double factor;
    };
    std::vector<Row> rows = {
        {"base surface only", "base", Technique::Base, NormalMode::Approximate, MipSelection::Off, factor},
        {"displaced, approximate normals", "approximate", Technique::Displaced, NormalMode::Approximate, MipSelection::Off, factor},
        {"displaced, accurate normals", "accurate", Technique::Displaced, NormalMode::Accurate, MipSelection::Off, factor},
        {"displaced, auto normals", "auto", Technique::Displaced, NormalMode::Auto, MipSelection::Off, factor},
        {"displaced, approximate, LOD on", "approximate_lod", Technique::Displaced, NormalMode::Approximate, MipSelection::TessFactor, factor},
        {"displaced, accurate, LOD on", "accurate_lod", Technique::Displaced, NormalMode::Accurate, MipSelection::TessFactor, factor},
        {"baseline: height + normal map", "baseline", Technique::Baseline, NormalMode::Approximate, MipSelection::Off, factor},
    };
    if (a.factorSweep)
        for (int f : {2, 4, 8, 16, 32, 64}) {
            rows.push_back({"approximate, LOD on, factor " + std::to_string(f), "", Technique::Displaced, NormalMode::Approximate,
                            MipSelection::TessFactor, double(f)});
            rows.push_back({"baseline, factor " + std::to_string(f), "", Technique::Baseline, NormalMode::Approximate,
                            MipSelection::Off, double(f)});
        }

    CsvOut csv(a.csvPath, "variant,factor,gpu_ms,ratio_to_base,triangles,rms_color,mean_normal_deg,max_normal_deg,coverage_mismatch,"
                          "shading_mean_deg,shading_max_deg");
    out << "Renderer (" << (a.scene.empty() ? std::string("default scene") : "scene " + a.scene) << ", " << scene.width << " x " << scene.height << ", uniform factors, fractional_even; device "
        << ctx->deviceName() << (ctx->isSoftware() ? ": a CPU implementation, so GPU time here is CPU time" : "") << ").\n"
        << "GPU time: median of " << a.frames << " frames after " << a.warmup << " untimed (timestamp queries). Error against an accurate-normal, factor-64,\n"
        << "no-mip render of the same scene: RMS of the 8-bit colour, mean/max angle between normals where both\n"
        << "cover the pixel, share of pixels covered by only one. Shading: the normal's angle to the accurate\n"
        << "normal of the same geometry (same factor and LOD, so the pixels see the same surface points).\n";
    out << std::left << std::setw(36) << "variant" << std::right << std::setw(7) << "factor" << std::setw(10) << "GPU ms"
        << std::setw(9) << "x base" << std::setw(10) << "triangles" << std::setw(9) << "RMS rgb" << std::setw(10) << "mean deg"
        << std::setw(9) << "max deg" << std::setw(9) << "cover%" << std::setw(10) << "shade deg" << std::setw(9) << "max" << "\n";
    double baseMs = 0;
    for (const Row& row : rows) {
        Scene sc = scene;
        sc.effects.technique = row.technique;
        sc.effects.normals = row.normals;
        sc.effects.lod = row.lod;
        sc.effects.tessValue = row.factor;
        vulkan::SurfaceRenderer r(*ctx, sc, s.surface, row.technique == Technique::Baseline ? &atlas : nullptr);
        const vulkan::RenderedImage im = r.render(a.frames, a.warmup);
        if (row.technique == Technique::Base && row.factor == factor) baseMs = im.stats.gpuMs;
        const vulkan::ImageError e = vulkan::compareImages(im, ref);
        // The same geometry with accurate normals: what the normal mode alone costs in shading.
        Scene acc = sc;
        acc.effects.technique = Technique::Displaced;
        acc.effects.normals = NormalMode::Accurate;
        const vulkan::ImageError shade = vulkan::compareImages(im, vulkan::SurfaceRenderer(*ctx, acc, s.surface).render(1, 0));
        if (!a.imageDir.empty() && !row.file.empty()) writePng(im, a.imageDir + "/" + row.file + ".png");
        const double ratio = baseMs > 0 ? im.stats.gpuMs / baseMs : 0.0;
        out << std::left << std::setw(36) << row.name << std::right << std::setw(7) << row.factor << std::setw(10)
            << fixed(im.stats.gpuMs, 2) << std::setw(9) << fixed(ratio, 2) << std::setw(10) << im.stats.triangles << std::setw(9)
            << fixed(e.rmsColor, 2) << std::setw(10) << fixed(e.meanNormalDeg, 3) << std::setw(9) << fixed(e.maxNormalDeg, 2)
            << std::setw(9) << fixed(100.0 * e.coverageMismatch, 2) << std::setw(10) << fixed(shade.meanNormalDeg, 3) << std::setw(9)
            << fixed(shade.maxNormalDeg, 2) << "\n";
        csv << '"' << row.name << "\"," << row.factor << "," << im.stats.gpuMs << "," << ratio << "," << im.stats.triangles << ","
            << e.rmsColor << "," << e.meanNormalDeg << "," << e.maxNormalDeg << "," << e.coverageMismatch << "," << shade.meanNormalDeg
            << "," << shade.maxNormalDeg << "\n";
    }
    csv.commit();

    // Effects that are off cost nothing: the full shaders specialised with every optional
    // effect off, against the shaders compiled without them (DM_LEAN), alternating to share
    // the machine's noise; and the wireframe pass, which exists only when asked for.
    out << "\nEffects switched off against effects not built (displaced, approximate, LOD off, factor " << factor << "):\n";
    Scene sc = scene;
    sc.effects.technique = Technique::Displaced;
    sc.effects.normals = NormalMode::Approximate;
    sc.effects.lod = MipSelection::Off;
    sc.effects.tessValue = factor;
    vulkan::RendererOptions lean;
    lean.lean = true;
    vulkan::SurfaceRenderer full(*ctx, sc, s.surface), built(*ctx, sc, s.surface, nullptr, lean);
    std::vector<double> tf, tl;
    for (int round = 0; round < 5; ++round) {
        tf.push_back(full.render(a.frames, a.warmup).stats.gpuMs);
        tl.push_back(built.render(a.frames, a.warmup).stats.gpuMs);
    }
    std::sort(tf.begin(), tf.end());
    std::sort(tl.begin(), tl.end());
    out << "  specialised off: " << fixed(tf[2], 2) << " ms; not built: " << fixed(tl[2], 2) << " ms; ratio "
        << fixed(tf[2] / tl[2], 3) << " (medians of 5 alternating rounds of " << a.frames << " frames)\n";
    sc.effects.wireframe = true;
    const vulkan::RenderedImage wire = vulkan::SurfaceRenderer(*ctx, sc, s.surface).render(a.frames, a.warmup);
    out << "  with the wireframe overlay (a second pipeline, built only when asked for): " << fixed(wire.stats.gpuMs, 2)
        << " ms, " << fixed(wire.stats.gpuMs / tl[1], 2) << "x\n";
    if (!a.imageDir.empty()) writePng(wire, a.imageDir + "/wireframe.png");
}

} // namespace dispmap::figures
