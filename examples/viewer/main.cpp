// dispmap_viewer: an interactive viewer of dispmap scenes (the counterpart of OpenSubdiv's ptex
// viewer), built on the Vulkan backend the way an engine uses it: the viewer owns the window,
// instance, device, swapchain and command buffers; dispmap records into them.
//
//   dispmap_viewer [SCENE.json]                       interactive (keys printed at start)
//   dispmap_viewer --scene S.json --frames 4 --screenshot out.png [--compare-offscreen]
//                                                     headless test: N frames into the window's
//                                                     swapchain (under xvfb-run), then exit
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <string>

#include "viewer.h"

namespace {

const char* const kUsage =
    "usage: dispmap_viewer [SCENE.json] [options]\n"
    "  SCENE.json, --scene FILE  scene (as `dispmap render --scene`; surface or mesostructure); default: the embedded scene\n"
    "  --frames N                render N frames with the scene's camera and resolution, then exit (headless tests)\n"
    "  --screenshot FILE.png     with --frames: the last presented image as PNG\n"
    "  --compare-offscreen       with --frames: compare it with SurfaceRenderer::render() of the same draw;\n"
    "                            exit status 1 above the tolerance\n"
    "  --tolerance-rms X         largest accepted RMS difference (8-bit RGB; default 0)\n"
    "  --tolerance-max N         largest accepted difference of one channel (default 0)\n"
    "  --keys KEYS               keys pressed before the first frame, e.g. tw+ (see the key list)\n"
    "  --animate                 start with the animated cage\n"
    "  --device D                Vulkan device: index or name substring (default: DISPMAP_VK_DEVICE, else lavapipe)\n"
    "  --validation              Vulkan validation (also DISPMAP_VK_VALIDATION=1); any message fails the run\n"
    "  --faces-per-draw N        faces per draw call, 1..32 (default 16; lavapipe runs one draw on one thread)\n";

double number(const std::string& option, const std::string& value, double lo, double hi) {
    std::size_t used = 0;
    double x = 0;
    try {
        x = std::stod(value, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used != value.size() || !(x >= lo && x <= hi))
        throw std::invalid_argument(option + ": '" + value + "' is not a number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return x;
}

int integer(const std::string& option, const std::string& value, int lo, int hi) {
    const double x = number(option, value, lo, hi);
    if (x != std::floor(x)) throw std::invalid_argument(option + ": '" + value + "' is not an integer");
    return static_cast<int>(x);
}

// Parses argv into o; throws std::invalid_argument naming the option.
void parse(int argc, char** argv, viewer::ViewerOptions& o) {
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
            return argv[++i];
        };
        if (a == "--scene") o.scene = value();
        else if (a == "--frames") o.frames = integer(a, value(), 1, 100000);
        else if (a == "--screenshot") o.screenshot = value();
        else if (a == "--compare-offscreen") o.compareOffscreen = true;
        else if (a == "--tolerance-rms") o.toleranceRms = number(a, value(), 0, 255);
        else if (a == "--tolerance-max") o.toleranceMax = number(a, value(), 0, 255);
        else if (a == "--keys") o.keys = value();
        else if (a == "--animate") o.animate = true;
        else if (a == "--device") o.device = value();
        else if (a == "--validation") o.validation = true;
        else if (a == "--faces-per-draw") o.facesPerDraw = integer(a, value(), 1, 32); // as `dispmap render` (docs/lavapipe.md)
        else if (!a.empty() && a[0] != '-' && o.scene.empty()) o.scene = a;
        else throw std::invalid_argument("unknown argument '" + a + "'");
    }
    if (o.frames == 0 && (!o.screenshot.empty() || o.compareOffscreen))
        throw std::invalid_argument("--screenshot and --compare-offscreen need --frames");
}

} // namespace

int main(int argc, char** argv) {
    viewer::ViewerOptions o;
    for (int i = 1; i < argc; ++i)
        if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") {
            std::cout << kUsage << "\n" << viewer::kKeyHelp;
            return 0;
        }
    try {
        parse(argc, argv, o);
    } catch (const std::invalid_argument& e) {
        std::cerr << "dispmap_viewer: " << e.what() << "\n" << kUsage;
        return 2;
    }
    if (const char* v = std::getenv("DISPMAP_VK_VALIDATION"); v && *v && std::string(v) != "0") o.validation = true;

    glfwSetErrorCallback([](int code, const char* what) { std::cerr << "GLFW error " << code << ": " << what << "\n"; });
    if (!glfwInit()) {
        std::cerr << "dispmap_viewer: glfwInit failed (no display? run under xvfb-run for the headless mode)\n";
        return 1;
    }
    int status = 1;
    try {
        if (o.frames == 0) std::cout << viewer::kKeyHelp;
        viewer::Viewer v(o);
        status = v.run();
    } catch (const std::exception& e) {
        std::cerr << "dispmap_viewer: " << e.what() << "\n";
        status = 1;
    }
    glfwTerminate();
    return status;
}
