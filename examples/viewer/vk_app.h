#pragma once
// The viewer's own Vulkan objects, made the way an engine makes them: a VkInstance with GLFW's
// surface extensions (and the validation layer when DISPMAP_VK_VALIDATION=1), the window's
// surface, a physical device with a graphics queue that can present, and a VkDevice with
// VK_KHR_swapchain, dynamic rendering and the features the dispmap renderer needs. dispmap
// only borrows them (dispmap::vulkan::ExternalDevice).
//
// dispmap::vulkan defines VK_NO_PROTOTYPES for its users, so the viewer loads the functions it
// calls itself, through the vkGetInstanceProcAddr of the loader GLFW opened.
#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <mutex>
#include <string>
#include <vector>

#include "dispmap/vulkan/context.h"

namespace viewer {

#define VIEWER_VK_GLOBAL(X)                                                                                  \
    X(vkCreateInstance)                                                                                      \
    X(vkEnumerateInstanceLayerProperties)                                                                    \
    X(vkEnumerateInstanceExtensionProperties)
#define VIEWER_VK_INSTANCE(X)                                                                                \
    X(vkDestroyInstance)                                                                                     \
    X(vkEnumeratePhysicalDevices)                                                                            \
    X(vkGetPhysicalDeviceProperties)                                                                         \
    X(vkGetPhysicalDeviceFeatures)                                                                           \
    X(vkGetPhysicalDeviceFeatures2)                                                                          \
    X(vkGetPhysicalDeviceQueueFamilyProperties)                                                              \
    X(vkGetPhysicalDeviceMemoryProperties)                                                                   \
    X(vkGetPhysicalDeviceFormatProperties)                                                                   \
    X(vkEnumerateDeviceExtensionProperties)                                                                  \
    X(vkCreateDevice)                                                                                        \
    X(vkGetDeviceProcAddr)                                                                                   \
    X(vkDestroySurfaceKHR)                                                                                   \
    X(vkGetPhysicalDeviceSurfaceSupportKHR)                                                                  \
    X(vkGetPhysicalDeviceSurfaceCapabilitiesKHR)                                                             \
    X(vkGetPhysicalDeviceSurfaceFormatsKHR)                                                                  \
    X(vkGetPhysicalDeviceSurfacePresentModesKHR)
#define VIEWER_VK_DEBUG(X)                                                                                   \
    X(vkCreateDebugUtilsMessengerEXT)                                                                        \
    X(vkDestroyDebugUtilsMessengerEXT)
#define VIEWER_VK_DEVICE(X)                                                                                  \
    X(vkDestroyDevice)                                                                                       \
    X(vkGetDeviceQueue)                                                                                      \
    X(vkDeviceWaitIdle)                                                                                      \
    X(vkQueueSubmit)                                                                                         \
    X(vkQueuePresentKHR)                                                                                     \
    X(vkCreateSwapchainKHR)                                                                                  \
    X(vkDestroySwapchainKHR)                                                                                 \
    X(vkGetSwapchainImagesKHR)                                                                               \
    X(vkAcquireNextImageKHR)                                                                                 \
    X(vkCreateImage)                                                                                         \
    X(vkDestroyImage)                                                                                        \
    X(vkGetImageMemoryRequirements)                                                                          \
    X(vkBindImageMemory)                                                                                     \
    X(vkCreateImageView)                                                                                     \
    X(vkDestroyImageView)                                                                                    \
    X(vkCreateBuffer)                                                                                        \
    X(vkDestroyBuffer)                                                                                       \
    X(vkGetBufferMemoryRequirements)                                                                         \
    X(vkBindBufferMemory)                                                                                    \
    X(vkAllocateMemory)                                                                                      \
    X(vkFreeMemory)                                                                                          \
    X(vkMapMemory)                                                                                           \
    X(vkUnmapMemory)                                                                                         \
    X(vkCreateCommandPool)                                                                                   \
    X(vkDestroyCommandPool)                                                                                  \
    X(vkAllocateCommandBuffers)                                                                              \
    X(vkResetCommandBuffer)                                                                                  \
    X(vkBeginCommandBuffer)                                                                                  \
    X(vkEndCommandBuffer)                                                                                    \
    X(vkCreateFence)                                                                                         \
    X(vkDestroyFence)                                                                                        \
    X(vkWaitForFences)                                                                                       \
    X(vkResetFences)                                                                                         \
    X(vkCreateSemaphore)                                                                                     \
    X(vkDestroySemaphore)                                                                                    \
    X(vkCreateQueryPool)                                                                                     \
    X(vkDestroyQueryPool)                                                                                    \
    X(vkGetQueryPoolResults)                                                                                 \
    X(vkCmdResetQueryPool)                                                                                   \
    X(vkCmdBeginQuery)                                                                                       \
    X(vkCmdEndQuery)                                                                                         \
    X(vkCmdWriteTimestamp)                                                                                   \
    X(vkCmdPipelineBarrier)                                                                                  \
    X(vkCmdCopyImageToBuffer)                                                                                \
    X(vkCmdCopyBufferToImage)

/// The functions the viewer calls (the renderer has its own table in its Context).
struct Vk {
    PFN_vkGetInstanceProcAddr vkGetInstanceProcAddr = nullptr;
#define VIEWER_VK_MEMBER(name) PFN_##name name = nullptr;
    VIEWER_VK_GLOBAL(VIEWER_VK_MEMBER)
    VIEWER_VK_INSTANCE(VIEWER_VK_MEMBER)
    VIEWER_VK_DEBUG(VIEWER_VK_MEMBER)
    VIEWER_VK_DEVICE(VIEWER_VK_MEMBER)
#undef VIEWER_VK_MEMBER
    // Core in Vulkan 1.3, else VK_KHR_dynamic_rendering's ...KHR names (the same signatures).
    PFN_vkCmdBeginRendering vkCmdBeginRendering = nullptr;
    PFN_vkCmdEndRendering vkCmdEndRendering = nullptr;
};

/// Throws dispmap::vulkan::VulkanError "<call> failed: <result>" unless result is VK_SUCCESS.
#define VIEWER_CHECK(call) ::dispmap::vulkan::check((call), #call)

struct AppOptions {
    std::string device;      ///< empty: the first device whose name has "llvmpipe", else the first that can present
    bool validation = false; ///< VK_LAYER_KHRONOS_validation + a messenger recording warnings and errors
};

/// Instance, surface, device and queue of the viewer's window. Destroyed in reverse order.
class VulkanApp {
  public:
    VulkanApp(GLFWwindow* window, const AppOptions& options);
    ~VulkanApp();
    VulkanApp(const VulkanApp&) = delete;
    VulkanApp& operator=(const VulkanApp&) = delete;

    const Vk& vk() const { return vk_; }
    VkInstance instance() const { return instance_; }
    VkSurfaceKHR surface() const { return surface_; }
    VkPhysicalDevice physicalDevice() const { return physicalDevice_; }
    VkDevice device() const { return device_; }
    VkQueue queue() const { return queue_; }
    std::uint32_t queueFamily() const { return queueFamily_; }
    const std::string& deviceName() const { return deviceName_; }
    const VkPhysicalDeviceProperties& properties() const { return properties_; }
    bool statisticsQueries() const { return enabled_.pipelineStatisticsQuery == VK_TRUE; }

    /// What dispmap::vulkan::Context(ExternalDevice) borrows.
    dispmap::vulkan::ExternalDevice external() const;

    /// Memory type index with typeBits and all flags; VulkanError if none.
    std::uint32_t memoryType(std::uint32_t typeBits, VkMemoryPropertyFlags flags) const;

    /// The validation messages of the viewer's own messenger since the last call.
    std::vector<std::string> takeMessages();

  private:
    void create(GLFWwindow* window, const AppOptions& options);
    void destroy() noexcept;
    static VKAPI_ATTR VkBool32 VKAPI_CALL onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                    VkDebugUtilsMessageTypeFlagsEXT types,
                                                    const VkDebugUtilsMessengerCallbackDataEXT* data, void* self);

    Vk vk_{};
    VkInstance instance_ = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
    VkSurfaceKHR surface_ = VK_NULL_HANDLE;
    VkPhysicalDevice physicalDevice_ = VK_NULL_HANDLE;
    VkPhysicalDeviceProperties properties_{};
    std::string deviceName_;
    VkPhysicalDeviceFeatures enabled_{};
    std::uint32_t queueFamily_ = 0;
    VkDevice device_ = VK_NULL_HANDLE;
    VkQueue queue_ = VK_NULL_HANDLE;
    std::mutex messagesMutex_;
    std::vector<std::string> messages_;
};

} // namespace viewer
