// The viewer (viewer.h): window, input, the renderer's life cycle, the frame loop.
#include "viewer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "dispmap/io/png.h"

namespace viewer {

using dispmap::vulkan::VulkanError;

const char* const kKeyHelp =
    "keys:\n"
    "  1 / 2 / 3   normals: approximate / accurate / auto\n"
    "  L           level of detail of the displacement: off / tess factor / texel ratio\n"
    "  M           tessellation factors: uniform / distance / screen edge / screen area\n"
    "  + / -       the factor (uniform) or the method's constant c, x1.25 / /1.25\n"
    "  W           wireframe overlay\n"
    "  T           technique: displaced / baseline (height + normal map) / base surface\n"
    "  A           animated cage (control points moved by a sine wave every frame)\n"
    "  R           reset the camera\n"
    "  Esc / Q     quit\n"
    "  mouse       left drag orbits, wheel zooms\n"
    "  (mesostructure scenes: only the camera keys and the mouse)\n";

namespace {

constexpr double kPi = 3.14159265358979323846;

Viewer* self(GLFWwindow* w) { return static_cast<Viewer*>(glfwGetWindowUserPointer(w)); }

} // namespace

std::string fixed(double x, int digits) {
    std::ostringstream s;
    s << std::fixed << std::setprecision(digits) << x;
    return s.str();
}

Orbit Orbit::around(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up) {
    Orbit o;
    o.target = target;
    o.up = glm::normalize(up);
    const glm::dvec3 offset = eye - target;
    o.distance = glm::length(offset);
    const glm::dvec3 dir = offset / o.distance;
    o.pitch = std::asin(std::clamp(glm::dot(dir, o.up), -1.0, 1.0));
    glm::dvec3 h = dir - o.up * glm::dot(dir, o.up);
    if (glm::length(h) < 1e-9) h = std::abs(o.up.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    o.axisA = glm::normalize(h - o.up * glm::dot(h, o.up));
    o.axisB = glm::cross(o.up, o.axisA);
    return o;
}

glm::dvec3 Orbit::eye() const {
    const glm::dvec3 horizontal = std::cos(yaw) * axisA + std::sin(yaw) * axisB;
    return target + distance * (std::cos(pitch) * horizontal + std::sin(pitch) * up);
}

Viewer::Viewer(const ViewerOptions& options) : options_(options) {
    // The scene: a mesostructure scene has a "mesostructure" key.
    int width = 0, height = 0;
    if (!options_.scene.empty()) {
        // Read once, with the scene reader's limits (size, nesting depth), as `dispmap render` does.
        const nlohmann::json j = dispmap::loadSceneJson(options_.scene);
        meso_ = dispmap::isMesoScene(j);
        if (meso_) {
            mesoScene_ = dispmap::parseMesoScene(j, options_.scene, std::filesystem::path(options_.scene).parent_path().string());
            mesoGpu_ = dispmap::figures::buildMesoSceneGpu(mesoScene_);
            width = mesoScene_.width;
            height = mesoScene_.height;
            orbit_ = Orbit::around(mesoScene_.eye, mesoScene_.target, mesoScene_.up);
            if (!mesoGpu_.options.base) orbit_.minPitch = 0.05; // the renderer needs the camera above the plane
        } else {
            scene_ = dispmap::parseSceneDocument(j, options_.scene, std::filesystem::path(options_.scene).parent_path().string());
        }
    } else {
        scene_ = dispmap::defaultScene();
    }
    if (!meso_) {
        std::cout << "building the surface of scene '" << scene_.name << "' (" << scene_.mesh << ", isolation " << scene_.isolation
                  << ")..." << std::endl;
        surface_ = std::make_unique<dispmap::SceneSurface>(scene_);
        rest_ = surface_->mesh.description().positions;
        width = scene_.width;
        height = scene_.height;
        orbit_ = Orbit::around(scene_.camera.eye, scene_.camera.target, scene_.camera.up);
        methodValue_[static_cast<int>(scene_.effects.tessMethod)] = scene_.effects.tessValue;
        animating_ = options_.animate;
    }
    if (options_.frames == 0 && width < 800) { // interactive: a window of a useful size
        height = height * 800 / width;
        width = 800;
    }

    // The window: no OpenGL context, fixed size in the headless mode (the comparison needs the
    // scene's size).
    if (!glfwVulkanSupported()) throw VulkanError("GLFW found no Vulkan loader (libvulkan.so.1)");
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    glfwWindowHint(GLFW_RESIZABLE, options_.frames > 0 ? GLFW_FALSE : GLFW_TRUE);
    window_ = glfwCreateWindow(width, height, "dispmap viewer", nullptr, nullptr);
    if (!window_) throw VulkanError("glfwCreateWindow failed");
    glfwSetWindowUserPointer(window_, this);
    glfwSetKeyCallback(window_, [](GLFWwindow* w, int key, int, int action, int) {
        if (action == GLFW_PRESS || (action == GLFW_REPEAT && (key == GLFW_KEY_EQUAL || key == GLFW_KEY_MINUS ||
                                                              key == GLFW_KEY_KP_ADD || key == GLFW_KEY_KP_SUBTRACT)))
            self(w)->onKey(key);
    });
    glfwSetCursorPosCallback(window_, [](GLFWwindow* w, double x, double y) { self(w)->onCursor(x, y); });
    glfwSetMouseButtonCallback(window_, [](GLFWwindow* w, int button, int action, int) { self(w)->onButton(button, action); });
    glfwSetScrollCallback(window_, [](GLFWwindow* w, double, double dy) { self(w)->onScroll(dy); });

    // The engine's Vulkan objects, then dispmap's Context on them.
    AppOptions ao;
    ao.device = options_.device;
    ao.validation = options_.validation;
    app_ = std::make_unique<VulkanApp>(window_, ao);
    presenter_ = std::make_unique<Presenter>(*app_, window_);
    context_ = std::make_unique<dispmap::vulkan::Context>(app_->external());
    std::cout << "device: " << app_->deviceName() << ", swapchain " << presenter_->extent().width << " x " << presenter_->extent().height
              << (presenter_->colorFormat() == VK_FORMAT_B8G8R8A8_UNORM ? " B8G8R8A8_UNORM" : " R8G8B8A8_UNORM")
              << (app_->statisticsQueries() ? "" : " (no pipeline statistics queries: no triangle count)") << std::endl;

    for (char k : options_.keys)
        if (!press(k)) throw dispmap::ArgumentError(std::string("--keys: '") + k + "' is not a key of this scene");
}

Viewer::~Viewer() {
    if (presenter_) presenter_->waitIdle();
    renderer_.reset();
    if (app_) {
        if (staging_) app_->vk().vkDestroyBuffer(app_->device(), staging_, nullptr);
        if (stagingMemory_) app_->vk().vkFreeMemory(app_->device(), stagingMemory_, nullptr);
    }
    context_.reset();
    presenter_.reset();
    app_.reset();
    if (window_) glfwDestroyWindow(window_);
}

// --- input -----------------------------------------------------------------------------------

void Viewer::onKey(int key) {
    char c = 0;
    if (key >= GLFW_KEY_A && key <= GLFW_KEY_Z) c = static_cast<char>('a' + (key - GLFW_KEY_A));
    else if (key >= GLFW_KEY_1 && key <= GLFW_KEY_3) c = static_cast<char>('1' + (key - GLFW_KEY_1));
    else if (key == GLFW_KEY_EQUAL || key == GLFW_KEY_KP_ADD) c = '+';
    else if (key == GLFW_KEY_MINUS || key == GLFW_KEY_KP_SUBTRACT) c = '-';
    else if (key == GLFW_KEY_ESCAPE) c = 27;
    if (c) press(c);
}

bool Viewer::press(char key) {
    using namespace dispmap;
    if (key == 27 || key == 'q') {
        quit_ = true;
        return true;
    }
    if (key == 'r') {
        orbit_ = meso_ ? Orbit::around(mesoScene_.eye, mesoScene_.target, mesoScene_.up)
                       : Orbit::around(scene_.camera.eye, scene_.camera.target, scene_.camera.up);
        if (meso_ && !mesoGpu_.options.base) orbit_.minPitch = 0.05;
        orbitMoved_ = false;
        mesoDirty_ = true;
        return true;
    }
    if (meso_) return false;
    SurfaceEffects& e = scene_.effects;
    switch (key) {
    case '1': e.normals = NormalMode::Approximate; break;
    case '2': e.normals = NormalMode::Accurate; break;
    case '3': e.normals = NormalMode::Auto; break;
    case 'l':
        e.lod = e.lod == MipSelection::Off ? MipSelection::TessFactor : e.lod == MipSelection::TessFactor ? MipSelection::TexelRatio : MipSelection::Off;
        break;
    case 'm':
        methodValue_[static_cast<int>(e.tessMethod)] = e.tessValue;
        e.tessMethod = static_cast<TessMethod>((static_cast<int>(e.tessMethod) + 1) % 4);
        e.tessValue = methodValue_[static_cast<int>(e.tessMethod)];
        break;
    case 'w': e.wireframe = !e.wireframe; break;
    case 't':
        e.technique = e.technique == Technique::Displaced ? Technique::Baseline : e.technique == Technique::Baseline ? Technique::Base : Technique::Displaced;
        break;
    case '+':
    case '-': {
        double v = key == '+' ? e.tessValue * 1.25 : e.tessValue / 1.25;
        if (e.tessMethod == TessMethod::Uniform) v = std::clamp(v, 1.0, e.maxFactor);
        e.tessValue = v;
        if (renderer_) renderer_->setTessValue(v); // a push value: no new pipelines
        std::cout << "factor " << (e.tessMethod == TessMethod::Uniform ? "" : "constant ") << fixed(v, 3) << std::endl;
        return true;
    }
    case 'a':
        animating_ = !animating_;
        if (!animating_ && cageMoved_) { // back to the rest cage
            surface_->base.setControlPoints(rest_);
            if (renderer_) renderer_->updateControlPoints();
            cageMoved_ = false;
        }
        std::cout << "animated cage " << (animating_ ? "on" : "off") << std::endl;
        return true;
    default: return false;
    }
    rebuild_ = true; // effects are specialisation constants: new pipelines
    std::cout << effectsText() << std::endl;
    return true;
}

void Viewer::onCursor(double x, double y) {
    if (dragging_) {
        orbit_.yaw -= 0.008 * (x - lastX_);
        orbit_.pitch = std::clamp(orbit_.pitch + 0.008 * (y - lastY_), orbit_.minPitch, orbit_.maxPitch);
        orbitMoved_ = true;
        mesoDirty_ = true;
    }
    lastX_ = x;
    lastY_ = y;
}

void Viewer::onButton(int button, int action) {
    if (button == GLFW_MOUSE_BUTTON_LEFT) dragging_ = action == GLFW_PRESS;
}

void Viewer::onScroll(double dy) {
    const double far = meso_ ? 20.0 : scene_.camera.farPlane;
    orbit_.distance = std::clamp(orbit_.distance * std::pow(0.9, dy), 0.1, 0.5 * far);
    orbitMoved_ = true;
    mesoDirty_ = true;
}

// --- drawing ---------------------------------------------------------------------------------

dispmap::Camera Viewer::camera() const {
    dispmap::Camera c = scene_.camera;
    if (orbitMoved_) { // untouched: exactly the scene's camera
        c.eye = orbit_.eye();
        c.up = orbit_.up;
    }
    return c;
}

dispmap::SurfaceDraw Viewer::currentDraw() const {
    dispmap::SurfaceDraw d = scene_;
    d.camera = camera();
    d.width = static_cast<int>(presenter_->extent().width);
    d.height = static_cast<int>(presenter_->extent().height);
    return d;
}

std::string Viewer::effectsText() const {
    if (meso_) {
        const char* methods[] = {"distance map", "DDM", "relief", "POM"};
        return std::string("mesostructure, ") + methods[static_cast<int>(mesoScene_.technique.method)] +
               (mesoScene_.shadows ? ", shadows" : "") + (mesoGpu_.parts.size() > 1 ? ", " + std::to_string(mesoGpu_.parts.size()) + " mesostructures" : "") +
               " (offscreen, copied into the swapchain image)";
    }
    const dispmap::SurfaceEffects& e = scene_.effects;
    using dispmap::detail::sceneChoiceName; // the scene files' spellings
    return std::string(toString(e.technique)) + ", normals " + sceneChoiceName(dispmap::detail::kSceneNormals, e.normals) + ", LOD " +
           sceneChoiceName(dispmap::detail::kSceneLods, e.lod) + ", " + toString(e.tessMethod) + " " + fixed(e.tessValue, e.tessMethod == dispmap::TessMethod::Uniform ? 1 : 3) +
           (e.wireframe ? ", wireframe" : "") + (animating_ ? ", animated" : "");
}

void Viewer::buildRenderer() {
    presenter_->waitIdle(); // the old pipelines may still be in use by a frame in flight
    renderer_.reset();
    if (scene_.effects.technique == dispmap::Technique::Baseline && !surface_->atlas)
        std::cout << "baking the baseline atlas..." << std::endl;
    const dispmap::BaselineAtlas* atlas = scene_.effects.technique == dispmap::Technique::Baseline ? &surface_->bake(scene_) : nullptr;
    dispmap::vulkan::RendererOptions o;
    o.facesPerDraw = options_.facesPerDraw;
    dispmap::vulkan::TargetFormats t;
    t.color = presenter_->colorFormat();
    t.normal = VK_FORMAT_UNDEFINED;
    t.depth = Presenter::kDepthFormat;
    o.target = t;
    renderer_ = std::make_unique<dispmap::vulkan::SurfaceRenderer>(*context_, currentDraw(), surface_->surface, atlas, o);
    rebuild_ = false;
    generation_ = presenter_->generation();
}

void Viewer::animate() {
    if (!animating_) return;
    // A deterministic clock (frames at 30 Hz), so that the headless test sees the same cage.
    const double t = animationFrame_++ / 30.0;
    glm::dvec3 lo(1e300), hi(-1e300);
    for (const glm::dvec3& p : rest_) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const glm::dvec3 centre = 0.5 * (lo + hi);
    const double amplitude = 0.06 * glm::length(hi - lo);
    std::vector<glm::dvec3> moved(rest_.size());
    for (std::size_t i = 0; i < rest_.size(); ++i) {
        const glm::dvec3 d = rest_[i] - centre;
        const double len = glm::length(d);
        const glm::dvec3 dir = len > 0 ? d / len : glm::dvec3(0, 1, 0);
        moved[i] = rest_[i] + amplitude * std::sin(2 * kPi * 0.5 * t + 3.0 * rest_[i].y + 2.0 * rest_[i].x) * dir;
    }
    surface_->base.setControlPoints(moved);
    renderer_->updateControlPoints(); // uploaded by the next recordUpdate
    cageMoved_ = true;
}

void Viewer::drawSurfaceFrame(bool screenshot) {
    if (generation_ != presenter_->generation()) {
        renderer_->setImageSize(static_cast<int>(presenter_->extent().width), static_cast<int>(presenter_->extent().height));
        generation_ = presenter_->generation();
    }
    renderer_->setCamera(camera());
    animate();
    const VkCommandBuffer cmd = presenter_->frame().cmd;
    renderer_->recordUpdate(cmd); // this frame's parameters and moved geometry, outside rendering
    presenter_->beginRendering(scene_.background, true);
    renderer_->recordDraw(cmd);
    presenter_->endRendering();
    presenter_->end(screenshot);
}

void Viewer::updateTitle(double frameMs) {
    frameMsSum_ += frameMs;
    ++frameCount_;
    const double now = glfwGetTime();
    if (now - titleTime_ < 0.5 && options_.frames == 0) return;
    std::string title = "dispmap viewer | " + effectsText() + " | " + fixed(frameMsSum_ / frameCount_, 1) + " ms/frame";
    if (stats_.valid && stats_.gpuMs > 0)
        title += meso_ ? " | offscreen render " + fixed(stats_.gpuMs, 1) + " ms GPU" : " (GPU " + fixed(stats_.gpuMs, 1) + " ms)";
    if (!meso_) {
        if (stats_.valid && app_->statisticsQueries())
            title += " | " + std::to_string(stats_.triangles) + " triangles, " + std::to_string(stats_.patches) + " patches";
        else
            title += " | triangle count unavailable (no pipeline statistics queries)";
    }
    glfwSetWindowTitle(window_, title.c_str());
    titleTime_ = now;
    frameMsSum_ = 0;
    frameCount_ = 0;
}

// --- the loop --------------------------------------------------------------------------------

bool Viewer::reportValidation() {
    bool any = false;
    std::vector<std::string> messages = app_->takeMessages();
    for (std::string& m : context_->takeValidationMessages()) messages.push_back(std::move(m));
    for (const std::string& m : messages) {
        std::cerr << "validation: " << m << "\n";
        validation_.push_back(m);
        any = true;
    }
    return any;
}

int Viewer::run() {
    const bool headless = options_.frames > 0;
    std::cout << "scene '" << (meso_ ? mesoScene_.name : scene_.name) << "': " << effectsText() << std::endl;
    double last = glfwGetTime();
    for (int frame = 0; !quit_ && !glfwWindowShouldClose(window_); ++frame) {
        // A mesostructure image is rendered again only when the camera moves: wait for input.
        if (meso_ && !mesoDirty_ && !headless) glfwWaitEventsTimeout(0.1);
        else glfwPollEvents();
        if (headless && frame >= options_.frames) break;
        if (!meso_ && rebuild_) buildRenderer();
        if (!presenter_->begin()) { // minimised
            glfwWaitEvents();
            continue;
        }
        if (presenter_->frame().previous.valid && !meso_) stats_ = presenter_->frame().previous;
        const bool screenshot = headless && frame == options_.frames - 1;
        if (meso_) drawMesoFrame(screenshot);
        else drawSurfaceFrame(screenshot);
        const double now = glfwGetTime();
        updateTitle(1e3 * (now - last));
        last = now;
        if (!headless) reportValidation();
    }
    presenter_->waitIdle();

    int status = 0;
    if (headless) {
        const std::vector<std::uint8_t> presented = presenter_->screenshot();
        const VkExtent2D e = presenter_->extent();
        if (!options_.screenshot.empty()) {
            dispmap::writeRgbaPng(options_.screenshot, static_cast<int>(e.width), static_cast<int>(e.height), presented.data());
            std::cout << "wrote " << options_.screenshot << " (" << e.width << " x " << e.height << ", the last of " << options_.frames
                      << " presented frames)" << std::endl;
        }
        if (stats_.valid && !meso_)
            std::cout << "last measured frame: " << stats_.triangles << " triangles, " << stats_.patches << " patches, GPU "
                      << fixed(stats_.gpuMs, 2) << " ms" << std::endl;
        if (options_.compareOffscreen) status = compare(presented);
    }
    if (reportValidation() || !validation_.empty()) {
        std::cerr << "FAILED: " << validation_.size() << " validation message(s)" << std::endl;
        status = 1;
    }
    return status;
}

} // namespace viewer
