// `dispmap maps --seams`: the paper's Figure 7 measured (docs/figures.md, "The traditional
// baseline at UV seams"): the traditional method on the mesh's own UV layout cracks and shows
// shading seams along UV seams; its seam-free per-face atlas and dispmap's tiles do not.
#include "uv_seams_table.h"
#include "maps_table.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "text_format.h"
#include "dispmap/io/image_files.h"
#include "dispmap/io/png.h"
#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/baseline.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/draw.h"
#include "dispmap/surface/map_source.h"
#include "dispmap/surface/mesh.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/vulkan/context.h"
#include "dispmap/vulkan/renderer.h"

namespace dispmap::figures {

namespace {


constexpr double kDeg = 57.29577951308232;

/// Three renders side by side (same size) with 4-pixel black gaps, as one RGBA image.
void writePanels(const std::string& path, const std::vector<const vulkan::RenderedImage*>& panels) {
    const int w = panels[0]->width, h = panels[0]->height, gap = 4;
    const int total = static_cast<int>(panels.size()) * w + (static_cast<int>(panels.size()) - 1) * gap;
    std::vector<std::uint8_t> rgba(4 * static_cast<std::size_t>(total) * static_cast<std::size_t>(h), 0);
    for (std::size_t i = 0; i < rgba.size(); i += 4) rgba[i + 3] = 255;
    for (std::size_t p = 0; p < panels.size(); ++p)
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (std::size_t c = 0; c < 4; ++c)
                    rgba[4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(total) + p * static_cast<std::size_t>(w + gap) +
                              static_cast<std::size_t>(x)) +
                         c] = panels[p]->rgba[4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)) + c];
    writeRgbaPng(path, total, h, rgba.data());
}

} // namespace

void printUvSeamsTable(std::ostream& out, const UvSeamsTableArgs& a) {
    using Clock = std::chrono::steady_clock;
    const ControlMesh spot = ControlMesh::fromObjFile(a.dataDir + "/spot_control_mesh.obj");
    HeightMaps brick;
    brick.images[0] = std::make_shared<const HeightImage>(readHeightImage(a.dataDir + "/skimage_brick.png"));
    const auto linear = std::make_shared<const UvMap>(spot, UvInterpolation::Linear);
    const int k = a.quick ? 4 : 5, n = 1 << k;
    const TileSet tiles = spotBrickTiles(spot, linear, brick, k);
    const BaseSurface base(spot);
    const DisplacedSurface surface(base, tiles);
    const int faces = base.faceCount();
    const int side = baselineUvSide(faces, n);

    struct Row {
        std::string name;
        std::size_t bytes = 0;
        double seconds = 0;
        UvSeamReport seams;
        std::shared_ptr<const BaselineAtlas> atlas; // null: dispmap
    };
    std::vector<Row> rows;
    const auto timed = [&](const std::string& name, auto make) {
        const auto t0 = Clock::now();
        auto atlas = std::make_shared<const BaselineAtlas>(make());
        Row r;
        r.name = name;
        r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        r.bytes = atlas->bytes();
        r.atlas = std::move(atlas);
        r.seams = measureUvSeams(surface, *linear, r.atlas.get());
        rows.push_back(std::move(r));
    };
    {
        Row r;
        r.name = "dispmap: tiles 2^" + std::to_string(k);
        r.bytes = tiles.pack().texels.size() * sizeof(float);
        r.seams = measureUvSeams(surface, *linear, nullptr);
        rows.push_back(std::move(r));
    }
    timed("baseline, chart per face, " + std::to_string(n) + " texels an edge", [&] { return bakeBaseline(surface, n); });
    const std::size_t uvRow = rows.size();
    timed("baseline, mesh UVs, " + std::to_string(side) + "^2, gutter 4", [&] { return bakeBaselineUv(surface, *linear, side, side, 4); });
    timed("baseline, mesh UVs, " + std::to_string(side) + "^2, no gutter", [&] { return bakeBaselineUv(surface, *linear, side, side, 0); });
    timed("baseline, mesh UVs, " + std::to_string(2 * side) + "^2, gutter 8",
          [&] { return bakeBaselineUv(surface, *linear, 2 * side, 2 * side, 8); });

    double dMax = 0.0;
    for (int t = 0; t < faces; ++t)
        for (int j = 0; j < 8; ++j)
            for (int i = 0; i < 8; ++i) dMax = std::max(dMax, std::abs(tiles.evaluate<double>(t, 0, glm::dvec2((i + 0.5) / 8, (j + 0.5) / 8))));
    const double size = rows[0].seams.size;
    out << "The traditional baseline at UV seams (the paper's Figure 7): Spot (" << faces << " faces, UV layout with "
        << rows[0].seams.seams.points << " seam points of " << rows[0].seams.seams.points + rows[0].seams.inside.points
        << ", " << rows[uvRow].atlas->sharedTexels << " texels of the mesh-UV image covered by two faces) with the 512 x 512 "
        << "brick map, max |D| " << sci(dMax / size) << " of the mesh size. Each technique evaluated on both "
        << "sides of every edge at 17 points (measureUvSeams): the crack (distance between the two sides' displaced points, of the "
        << "mesh size) and the shading jump (angle between the two sides' normals). The baselines are baked from dispmap's "
        << "surface, so all rows show the same surface; mesh UVs: bilinear over each face, per-vertex tangents:\n\n";
    out << "| technique | texture bytes | bake s | crack at seams: max / mean | shading jump at seams, deg: max / mean | "
           "crack inside charts: max | jump inside charts, deg: mean |\n|---|---:|---:|---:|---:|---:|---:|\n";
    for (const Row& r : rows)
        out << "| " << r.name << " | " << r.bytes << " | " << (r.atlas ? fixed(r.seconds, 2) : std::string("–")) << " | "
            << sci(r.seams.seams.maxGap) << " / " << sci(r.seams.seams.meanGap) << " | " << fixed(r.seams.seams.maxJump * kDeg, 2)
            << " / " << fixed(r.seams.seams.meanJump * kDeg, 2) << " | " << sci(r.seams.inside.maxGap) << " | "
            << fixed(r.seams.inside.meanJump * kDeg, 3) << " |\n";
    out << "\n";

    // On the GPU: the whole cow, and a close-up of the widest crack.
    vulkan::DeviceOptions dopt;
    dopt.device = a.device;
    vulkan::Context ctx(dopt);
    SurfaceDraw draw;
    draw.width = a.quick ? 480 : 960;
    draw.height = a.quick ? 360 : 720;
    draw.camera.eye = glm::dvec3(2.3, 0.8, -1.2);
    draw.camera.target = glm::dvec3(0, 0.25, 0);
    draw.camera.fovYDeg = 35;
    draw.effects.tessValue = 32;
    draw.effects.lod = MipSelection::Off;
    // A key light from above the camera and a fill from the side, so both charts of a seam are lit.
    draw.lights = {Light{glm::normalize(draw.camera.eye - draw.camera.target + glm::dvec3(0.0, 1.5, 0.0)), glm::dvec3(0.9)},
                   Light{glm::normalize(glm::dvec3(-1.0, 0.3, -0.5)), glm::dvec3(0.35)}};
    const auto render = [&](const BaselineAtlas* atlas) {
        draw.effects.technique = atlas ? Technique::Baseline : Technique::Displaced;
        vulkan::SurfaceRenderer r(ctx, draw, surface, atlas);
        return r.render(a.quick ? 1 : 3, 1);
    };
    const vulkan::RenderedImage ours = render(nullptr), perFace = render(rows[1].atlas.get()), uv = render(rows[uvRow].atlas.get());
    const double depthGap = 3.0 * dMax; // more than the displacement's whole range: seeing past the surface
    out << "Rendered on " << ctx.deviceName() << " at " << draw.width << " x " << draw.height << ", factor 32 (equal tessellation), "
        << "LOD off. Crack pixels: where a technique sees more than 3 max |D| behind the seam-free baseline's surface (or "
        << "background); enclosed background: background pixels inside the silhouette:\n\n";
    out << "| technique | crack pixels | enclosed background | GPU ms |\n|---|---:|---:|---:|\n";
    out << "| " << rows[0].name << " | " << vulkan::seeThroughPixels(ours, perFace, draw.camera, depthGap) << " | "
        << vulkan::enclosedBackground(ours) << " | " << fixed(ours.stats.gpuMs, 1) << " |\n";
    out << "| " << rows[1].name << " | – | " << vulkan::enclosedBackground(perFace) << " | " << fixed(perFace.stats.gpuMs, 1) << " |\n";
    out << "| " << rows[uvRow].name << " | " << vulkan::seeThroughPixels(uv, perFace, draw.camera, depthGap) << " | "
        << vulkan::enclosedBackground(uv) << " | " << fixed(uv.stats.gpuMs, 1) << " |\n\n";

    if (!a.images.empty()) {
        const UvSeamClass& worst = rows[uvRow].seams.seams;
        if (worst.worstFace < 0) throw ArgumentError("dispmap maps --seams: the mesh has no UV seams to look at");
        const SurfaceSample<double> s = surface.evaluate<double>(worst.worstFace, worst.worstUv.x, worst.worstUv.y, NormalMode::Accurate);
        SurfaceDraw close = draw;
        close.width = close.height = a.quick ? 240 : 400;
        close.camera.target = s.position;
        close.camera.eye = s.position + 0.3 * glm::normalize(s.baseNormal + glm::dvec3(0.0, 0.3, 0.0));
        close.camera.nearPlane = 0.01;
        close.camera.fovYDeg = 35;
        close.lights = {Light{glm::normalize(close.camera.eye - close.camera.target + glm::dvec3(0.0, 0.15, 0.0)), glm::dvec3(0.85)}};
        const auto renderClose = [&](const BaselineAtlas* atlas) {
            close.effects.technique = atlas ? Technique::Baseline : Technique::Displaced;
            return vulkan::SurfaceRenderer(ctx, close, surface, atlas).render(1, 0);
        };
        const vulkan::RenderedImage cu = renderClose(rows[uvRow].atlas.get()), cf = renderClose(rows[1].atlas.get()),
                                    co = renderClose(nullptr);
        writePanels(a.images + "/uv_seams_closeup.png", {&cu, &cf, &co});
        writePanels(a.images + "/uv_seams_whole.png", {&uv, &ours});
        out << "Pictures: " << a.images << "/uv_seams_closeup.png (the widest crack, face " << worst.worstFace
            << ": mesh-UV baseline, per-face baseline, dispmap) and uv_seams_whole.png (mesh-UV baseline, dispmap).\n\n";
    }
}

} // namespace dispmap::figures
