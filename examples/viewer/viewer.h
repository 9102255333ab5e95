#pragma once
// The viewer: a scene (surface or mesostructure) shown in a GLFW window through the viewer's
// own Vulkan device, swapchain and frames in flight (vk_app.h, presenter.h), with dispmap's
// SurfaceRenderer recording into the viewer's command buffers (recordUpdate before rendering,
// recordDraw inside the viewer's vkCmdBeginRendering), an orbit camera and keys for the effects.
// Mesostructure scenes are rendered offscreen by MesoRenderer and copied into the swapchain image.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dispmap/scene/meso.h"
#include "dispmap/scene/surface.h"
#include "dispmap/vulkan/meso_renderer.h"
#include "dispmap/vulkan/renderer.h"
#include "meso_scene_gpu.h"
#include "presenter.h"
#include "vk_app.h"

namespace viewer {

struct ViewerOptions {
    std::string scene;       ///< scene file (surface or mesostructure JSON); empty: the embedded default scene
    std::string device;      ///< Vulkan device (index or name substring); empty: DISPMAP_VK_DEVICE, else lavapipe
    bool validation = false; ///< also on with DISPMAP_VK_VALIDATION=1; any message makes the exit status 1
    int frames = 0;          ///< > 0: render this many frames with the scene's camera and size, then exit (headless tests)
    std::string screenshot;  ///< with frames: the last presented image as a PNG
    bool compareOffscreen = false; ///< with frames: compare the last presented image with SurfaceRenderer::render()
    double toleranceRms = 0, toleranceMax = 0; ///< the largest RMS / max 8-bit difference the comparison accepts
    std::string keys;        ///< keys pressed before the first frame ("t", "w+", "a"...: see kKeyHelp)
    bool animate = false;    ///< start with the animated cage
    int facesPerDraw = 16;
};

/// x with `digits` digits after the point.
std::string fixed(double x, int digits);

/// The keys, as printed at start.
extern const char* const kKeyHelp;

/// An orbit around a target: yaw about the up axis, pitch above the plane across it, distance.
struct Orbit {
    glm::dvec3 target{0}, up{0, 1, 0}, axisA{1, 0, 0}, axisB{0, 0, 1};
    double distance = 5, yaw = 0, pitch = 0;
    double minPitch = -1.55, maxPitch = 1.55;
    static Orbit around(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up);
    glm::dvec3 eye() const;
};

class Viewer {
  public:
    explicit Viewer(const ViewerOptions& options);
    ~Viewer();
    Viewer(const Viewer&) = delete;
    Viewer& operator=(const Viewer&) = delete;

    /// Runs until Esc / the window closes, or for options.frames frames; the exit status.
    int run();

  private:
    // Input (GLFW callbacks forward here).
    void onKey(int key);
    void onCursor(double x, double y);
    void onButton(int button, int action);
    void onScroll(double dy);
    /// One key of kKeyHelp, as a character ('1', 'l', '+', ...); false if it means nothing here.
    bool press(char key);

    void buildRenderer();
    void animate();
    void drawSurfaceFrame(bool screenshot);
    void drawMesoFrame(bool screenshot);
    void renderMesoImage();
    void updateTitle(double frameMs);
    std::string effectsText() const;
    dispmap::Camera camera() const;
    dispmap::SurfaceDraw currentDraw() const;
    int compare(const std::vector<std::uint8_t>& presented);
    bool reportValidation();

    ViewerOptions options_;
    bool meso_ = false;
    GLFWwindow* window_ = nullptr;
    std::unique_ptr<VulkanApp> app_;
    std::unique_ptr<Presenter> presenter_;
    std::unique_ptr<dispmap::vulkan::Context> context_;

    // Surface scenes.
    dispmap::Scene scene_;
    std::unique_ptr<dispmap::SceneSurface> surface_;
    std::unique_ptr<dispmap::vulkan::SurfaceRenderer> renderer_;
    bool rebuild_ = true;
    double methodValue_[4] = {16, 60, 0.2, 0.1}; ///< tessValue per TessMethod, kept across M
    std::vector<glm::dvec3> rest_;               ///< the cage's rest positions (animation)
    bool animating_ = false, cageMoved_ = false;
    int animationFrame_ = 0;

    // Mesostructure scenes.
    dispmap::MesoSceneDesc mesoScene_;
    dispmap::figures::MesoSceneGpu mesoGpu_; ///< its maps and parts (examples/dispmap/meso_scene_gpu.h)
    bool mesoDirty_ = true;
    VkBuffer staging_ = VK_NULL_HANDLE;
    VkDeviceMemory stagingMemory_ = VK_NULL_HANDLE;
    void* stagingMapped_ = nullptr;
    VkDeviceSize stagingSize_ = 0;
    std::vector<std::uint8_t> mesoRgba_;

    // Camera and input.
    Orbit orbit_;
    bool orbitMoved_ = false, dragging_ = false;
    double lastX_ = 0, lastY_ = 0;
    int generation_ = -1;
    bool quit_ = false;

    // Statistics shown in the title.
    double titleTime_ = 0, frameMsSum_ = 0;
    int frameCount_ = 0;
    FrameStats stats_;
    std::vector<std::string> validation_;
};

} // namespace viewer
