// The headless check of the viewer (viewer.h, --compare-offscreen): the last presented image
// against SurfaceRenderer::render() of the same draw, and against what the X server shows.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>

#include "viewer.h"
#include "x11_readback.h"

namespace viewer {

using dispmap::vulkan::VulkanError;

namespace {

// The 8-bit RGB difference of two RGBA images (alpha is not shown on screen).
struct Difference {
    double rms = 0;
    int max = 0;
    std::size_t differing = 0, pixels = 0;
    std::string text() const {
        return "RMS " + fixed(rms, 4) + ", max " + std::to_string(max) + " (8-bit RGB), " + std::to_string(differing) + " of " +
               std::to_string(pixels) + " pixels differ";
    }
};
Difference difference(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, std::size_t pixels) {
    Difference d;
    d.pixels = pixels;
    double sum = 0;
    for (std::size_t p = 0; p < pixels; ++p) {
        bool differs = false;
        for (std::size_t c = 0; c < 3; ++c) {
            const int x = std::abs(int{a[4 * p + c]} - int{b[4 * p + c]});
            sum += double(x) * x;
            d.max = std::max(d.max, x);
            differs = differs || x != 0;
        }
        d.differing += differs ? 1 : 0;
    }
    d.rms = std::sqrt(sum / (3.0 * static_cast<double>(pixels)));
    return d;
}

} // namespace

int Viewer::compare(const std::vector<std::uint8_t>& presented) {
    const VkExtent2D e = presenter_->extent();
    std::vector<std::uint8_t> reference;
    if (meso_) {
        // Rendered again offscreen (what was copied into the swapchain image came from the same call).
        renderMesoImage();
        reference = mesoRgba_;
    } else {
        // The same draw (effects, camera, size, the current cage) rendered offscreen into the
        // renderer's own targets and read back.
        const dispmap::BaselineAtlas* atlas = scene_.effects.technique == dispmap::Technique::Baseline ? &surface_->bake(scene_) : nullptr;
        dispmap::vulkan::RendererOptions o;
        o.facesPerDraw = options_.facesPerDraw;
        dispmap::vulkan::SurfaceRenderer offscreen(*context_, currentDraw(), surface_->surface, atlas, o);
        const dispmap::vulkan::RenderedImage im = offscreen.render(1, 0);
        if (im.width != static_cast<int>(e.width) || im.height != static_cast<int>(e.height))
            throw VulkanError("offscreen image " + std::to_string(im.width) + " x " + std::to_string(im.height) + " differs in size");
        reference = im.rgba;
        std::cout << "offscreen render: " << im.stats.triangles << " triangles, " << im.stats.patches << " patches" << std::endl;
    }
    const Difference d = difference(presented, reference, std::size_t{e.width} * e.height);
    const bool ok = d.rms <= options_.toleranceRms && d.max <= options_.toleranceMax;
    std::cout << "presented vs offscreen: " << d.text() << "; tolerance RMS " << options_.toleranceRms << ", max "
              << options_.toleranceMax << ": " << (ok ? "ok" : "FAILED") << std::endl;

    // What the X server shows in the window: the presented image reached the display. The
    // presentation engine talks to the server on its own connection, so wait for it a little.
    bool shown = true;
    for (int attempt = 0; attempt < 100; ++attempt) {
        const std::vector<std::uint8_t> screen = readX11Window(window_, static_cast<int>(e.width), static_cast<int>(e.height));
        if (screen.empty()) {
            std::cout << "X server window: not readable (not X11 or not a 24/32-bit TrueColor visual); not compared" << std::endl;
            break;
        }
        const Difference x = difference(screen, presented, std::size_t{e.width} * e.height);
        if (x.max == 0 || attempt == 99) {
            shown = x.max == 0;
            std::cout << "X server window vs presented: " << x.text() << (shown ? "" : ": FAILED") << std::endl;
            break;
        }
        glfwWaitEventsTimeout(0.02);
    }
    return ok && shown ? 0 : 1;
}

} // namespace viewer
