#pragma once
// The window's swapchain and everything per frame, as an engine keeps them: the swapchain with
// its image views, one depth image, two frames in flight (command buffer, fence, "image
// acquired" semaphore, a pipeline statistics and a timestamp query pool each) and one
// "rendering finished" semaphore per swapchain image. A frame is begin() ... end(): between
// them the caller records into frame().cmd, drawing with beginRendering()/endRendering()
// (dynamic rendering on the swapchain image and the depth image) or copying a finished image
// in with copyFromBuffer(). end(true) also copies the image it presents into a host buffer
// (screenshot()).
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "vk_app.h"

namespace viewer {

/// What the last completed use of a frame slot measured (queries read back after its fence).
struct FrameStats {
    bool valid = false;
    std::uint64_t patches = 0, triangles = 0; ///< tessellation control patches, primitives reaching the clipper
    double gpuMs = 0;                         ///< between the timestamps around the draw (0: none)
};

class Presenter {
  public:
    static constexpr int kFramesInFlight = 2;
    static constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

    Presenter(VulkanApp& app, GLFWwindow* window);
    ~Presenter();
    Presenter(const Presenter&) = delete;
    Presenter& operator=(const Presenter&) = delete;

    struct Frame {
        VkCommandBuffer cmd = VK_NULL_HANDLE;
        VkImage image = VK_NULL_HANDLE; ///< the acquired swapchain image
        std::uint32_t imageIndex = 0;
        FrameStats previous;            ///< what this slot measured the last time it was used
    };

    /// Waits for the slot, acquires an image (recreating the swapchain when it is out of date or
    /// the window changed size) and begins the command buffer. False while the window is minimised.
    bool begin();
    const Frame& frame() const { return frame_; }
    VkExtent2D extent() const { return extent_; }
    VkFormat colorFormat() const { return format_; }
    /// Counts up each time the swapchain is made again (the caller then resizes what it draws).
    int generation() const { return generation_; }

    /// Dynamic rendering on the swapchain image (cleared to `clear`) and the depth image (1).
    /// withQueries: the statistics query and the timestamps surround what is drawn.
    void beginRendering(const glm::dvec3& clear, bool withQueries);
    void endRendering();
    /// Copies width x height 32-bit texels in the swapchain's format from buffer into the image.
    void copyFromBuffer(VkBuffer buffer);
    /// Ends, submits and presents. screenshot: the presented image is also copied out.
    void end(bool screenshot);

    /// The last image end(true) copied, as RGBA8, row 0 at the top (waits for the device).
    std::vector<std::uint8_t> screenshot();

    /// Semaphores/fences done: waits for every frame in flight.
    void waitIdle();

  private:
    void createSwapchain();
    void destroySwapchain() noexcept;
    void destroy() noexcept;
    void barrier(VkImage image, VkImageAspectFlags aspect, VkImageLayout from, VkImageLayout to, VkPipelineStageFlags srcStage,
                 VkAccessFlags srcAccess, VkPipelineStageFlags dstStage, VkAccessFlags dstAccess) const;

    struct Slot {
        VkCommandBuffer cmd = VK_NULL_HANDLE;
        VkFence fence = VK_NULL_HANDLE;
        VkSemaphore acquired = VK_NULL_HANDLE;
        VkQueryPool statistics = VK_NULL_HANDLE, timestamps = VK_NULL_HANDLE;
        bool queried = false, timed = false;
    };

    VulkanApp& app_;
    GLFWwindow* window_;
    VkCommandPool pool_ = VK_NULL_HANDLE;
    std::array<Slot, kFramesInFlight> slots_{};
    int current_ = 0;
    Frame frame_{};
    bool timestamps_ = false;
    double timestampNs_ = 1;

    VkSwapchainKHR swapchain_ = VK_NULL_HANDLE;
    VkFormat format_ = VK_FORMAT_UNDEFINED;
    VkExtent2D extent_{0, 0};
    int generation_ = 0;
    std::vector<VkImage> images_;
    std::vector<VkImageView> views_;
    std::vector<VkSemaphore> rendered_; ///< per swapchain image
    VkImage depth_ = VK_NULL_HANDLE;
    VkDeviceMemory depthMemory_ = VK_NULL_HANDLE;
    VkImageView depthView_ = VK_NULL_HANDLE;
    VkBuffer readback_ = VK_NULL_HANDLE;
    VkDeviceMemory readbackMemory_ = VK_NULL_HANDLE;
    bool haveScreenshot_ = false;
    bool stale_ = false; ///< the presentation said out of date or suboptimal: made again at the next begin()
    // Where the acquired image is between the calls of one frame (layout, last stage and access).
    VkImageLayout layout_ = VK_IMAGE_LAYOUT_UNDEFINED;
    VkPipelineStageFlags stage_ = VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT;
    VkAccessFlags access_ = 0;
    void setState(VkImageLayout layout, VkPipelineStageFlags stage, VkAccessFlags access) {
        layout_ = layout;
        stage_ = stage;
        access_ = access;
    }
};

} // namespace viewer
