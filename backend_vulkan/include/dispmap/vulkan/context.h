#pragma once
// dispmap::vulkan: a headless Vulkan 1.2/1.3 instance, device and queue (lavapipe by default) or
// the caller's own (ExternalDevice), the table of Vulkan functions loaded at run time, one-shot
// submissions and compute dispatches.
// There is no link-time dependency on libvulkan: the Context dlopen()s the loader and fills a
// Functions table (VK_NO_PROTOTYPES is defined for every user of this target).
#include <cstdint>
#include <functional>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>
#include <vulkan/vulkan.h>

#include "dispmap/core/error.h"

namespace dispmap::vulkan {

/// Every failure of the backend: no loader, no device, a missing feature or layer, a failed call.
class VulkanError : public Error {
  public:
    using Error::Error;
};

/// The name of a result code ("VK_ERROR_OUT_OF_HOST_MEMORY"), or "VkResult(unknown)".
const char* resultName(VkResult result);

/// Throws VulkanError "<call> failed: <result name or number>" unless result is VK_SUCCESS.
void check(VkResult result, const char* call);

/// Calls fns.name(args...) and checks its result, e.g. DISPMAP_VK_CHECK(ctx.fn(), vkCreateFence, ...).
#define DISPMAP_VK_CHECK(fns, name, ...) ::dispmap::vulkan::check((fns).name(__VA_ARGS__), #name)

// The functions the backend loads, by level. Add a function here before using it; a function the
// loader or the driver does not provide is a VulkanError naming it when the Context is created.
#define DISPMAP_VK_GLOBAL_FUNCTIONS(X)                                                                       \
    X(vkCreateInstance)                                                                                      \
    X(vkEnumerateInstanceLayerProperties)
// Loaded where the loader has it (Vulkan 1.1 loaders and later); null otherwise.
#define DISPMAP_VK_OPTIONAL_GLOBAL_FUNCTIONS(X) X(vkEnumerateInstanceVersion)
#define DISPMAP_VK_INSTANCE_FUNCTIONS(X)                                                                     \
    X(vkDestroyInstance)                                                                                     \
    X(vkEnumeratePhysicalDevices)                                                                            \
    X(vkGetPhysicalDeviceProperties)                                                                         \
    X(vkGetPhysicalDeviceFeatures)                                                                           \
    X(vkGetPhysicalDeviceFeatures2)                                                                          \
    X(vkEnumerateDeviceExtensionProperties)                                                                  \
    X(vkGetPhysicalDeviceQueueFamilyProperties)                                                              \
    X(vkGetPhysicalDeviceMemoryProperties)                                                                   \
    X(vkGetPhysicalDeviceFormatProperties)                                                                   \
    X(vkCreateDevice)                                                                                        \
    X(vkGetDeviceProcAddr)
// Loaded only when validation is on (VK_EXT_debug_utils).
#define DISPMAP_VK_DEBUG_FUNCTIONS(X)                                                                        \
    X(vkCreateDebugUtilsMessengerEXT)                                                                        \
    X(vkDestroyDebugUtilsMessengerEXT)
#define DISPMAP_VK_DEVICE_FUNCTIONS(X)                                                                       \
    X(vkDestroyDevice)                                                                                       \
    X(vkGetDeviceQueue)                                                                                      \
    X(vkDeviceWaitIdle)                                                                                      \
    X(vkQueueSubmit)                                                                                         \
    X(vkCreateCommandPool)                                                                                   \
    X(vkDestroyCommandPool)                                                                                  \
    X(vkAllocateCommandBuffers)                                                                              \
    X(vkResetCommandBuffer)                                                                                  \
    X(vkBeginCommandBuffer)                                                                                  \
    X(vkEndCommandBuffer)                                                                                    \
    X(vkCreateFence)                                                                                         \
    X(vkDestroyFence)                                                                                        \
    X(vkResetFences)                                                                                         \
    X(vkWaitForFences)                                                                                       \
    X(vkCreateBuffer)                                                                                        \
    X(vkDestroyBuffer)                                                                                       \
    X(vkGetBufferMemoryRequirements)                                                                         \
    X(vkAllocateMemory)                                                                                      \
    X(vkFreeMemory)                                                                                          \
    X(vkBindBufferMemory)                                                                                    \
    X(vkMapMemory)                                                                                           \
    X(vkCreateShaderModule)                                                                                  \
    X(vkDestroyShaderModule)                                                                                 \
    X(vkCreateDescriptorSetLayout)                                                                           \
    X(vkDestroyDescriptorSetLayout)                                                                          \
    X(vkCreatePipelineLayout)                                                                                \
    X(vkDestroyPipelineLayout)                                                                               \
    X(vkCreateComputePipelines)                                                                              \
    X(vkDestroyPipeline)                                                                                     \
    X(vkCreateDescriptorPool)                                                                                \
    X(vkDestroyDescriptorPool)                                                                               \
    X(vkResetDescriptorPool)                                                                                 \
    X(vkAllocateDescriptorSets)                                                                              \
    X(vkUpdateDescriptorSets)                                                                                \
    X(vkCreateQueryPool)                                                                                     \
    X(vkDestroyQueryPool)                                                                                    \
    X(vkGetQueryPoolResults)                                                                                 \
    X(vkCmdResetQueryPool)                                                                                   \
    X(vkCmdWriteTimestamp)                                                                                   \
    X(vkCmdBindPipeline)                                                                                     \
    X(vkCmdBindDescriptorSets)                                                                               \
    X(vkCmdPushConstants)                                                                                    \
    X(vkCmdDispatch)                                                                                         \
    X(vkCmdPipelineBarrier)                                                                                  \
    X(vkCreateImage)                                                                                  \
    X(vkDestroyImage)                                                                                 \
    X(vkGetImageMemoryRequirements)                                                                   \
    X(vkBindImageMemory)                                                                              \
    X(vkCreateImageView)                                                                              \
    X(vkDestroyImageView)                                                                             \
    X(vkCreateSampler)                                                                                \
    X(vkDestroySampler)                                                                               \
    X(vkCreateRenderPass)                                                                             \
    X(vkDestroyRenderPass)                                                                            \
    X(vkCreateFramebuffer)                                                                            \
    X(vkDestroyFramebuffer)                                                                           \
    X(vkCreateGraphicsPipelines)                                                                      \
    X(vkCmdBeginRenderPass)                                                                           \
    X(vkCmdEndRenderPass)                                                                             \
    X(vkCmdDraw)                                                                                      \
    X(vkCmdCopyImageToBuffer)                                                                         \
    X(vkCmdCopyBufferToImage)                                                                         \
    X(vkCmdBeginQuery)                                                                                \
    X(vkCmdEndQuery)                                                                                  \
    X(vkCmdSetViewport)                                                                               \
    X(vkCmdSetScissor)                                                                                \
    X(vkCmdUpdateBuffer)
// Dynamic rendering, loaded only where it is enabled (Context::dynamicRenderingEnabled): the
// Vulkan 1.3 core functions, or those of VK_KHR_dynamic_rendering (same signatures) on 1.2.
#define DISPMAP_VK_RENDERING_FUNCTIONS(X)                                                                    \
    X(vkCmdBeginRendering)                                                                                   \
    X(vkCmdEndRendering)

/// The dispatch table: one pointer per function of the lists above, named like the function.
struct Functions {
    PFN_vkGetInstanceProcAddr vkGetInstanceProcAddr = nullptr;
#define DISPMAP_VK_MEMBER(name) PFN_##name name = nullptr;
    DISPMAP_VK_GLOBAL_FUNCTIONS(DISPMAP_VK_MEMBER)
    DISPMAP_VK_OPTIONAL_GLOBAL_FUNCTIONS(DISPMAP_VK_MEMBER)
    DISPMAP_VK_INSTANCE_FUNCTIONS(DISPMAP_VK_MEMBER)
    DISPMAP_VK_DEBUG_FUNCTIONS(DISPMAP_VK_MEMBER)
    DISPMAP_VK_DEVICE_FUNCTIONS(DISPMAP_VK_MEMBER)
    DISPMAP_VK_RENDERING_FUNCTIONS(DISPMAP_VK_MEMBER)
#undef DISPMAP_VK_MEMBER
};

/// Whether the device gets shaderFloat64 (double in shaders).
enum class Float64 : std::uint8_t {
    Off,         ///< not enabled
    IfSupported, ///< enabled where the device has it; see Context::float64Enabled()
    Required,    ///< enabled, or a VulkanError naming the device
};

/// How the Context picks and sets up its device.
struct DeviceOptions {
    /// Empty: the environment variable DISPMAP_VK_DEVICE, and if that is empty too, the first
    /// device whose name contains "llvmpipe" (lavapipe), else the first device. Otherwise a decimal
    /// index into the enumeration or a case-insensitive substring of the device name.
    std::string device{};
    /// VK_LAYER_KHRONOS_validation with a debug messenger (warnings and errors recorded); also
    /// switched on by DISPMAP_VK_VALIDATION=1.
    bool validation = false;
    Float64 float64 = Float64::Off;
};

/// The caller's own Vulkan objects, for an engine that embeds dispmap: the Context uses them and never destroys them.
struct ExternalDevice {
    PFN_vkGetInstanceProcAddr getInstanceProcAddr = nullptr; // from the caller's loader
    VkInstance instance = VK_NULL_HANDLE;
    VkPhysicalDevice physicalDevice = VK_NULL_HANDLE;
    VkDevice device = VK_NULL_HANDLE;
    VkQueue queue = VK_NULL_HANDLE;           // supports graphics and compute
    std::uint32_t queueFamily = 0;
    VkPhysicalDeviceFeatures enabledFeatures{}; // the core features the caller enabled
    bool dynamicRendering = false;            // the caller enabled dynamicRendering (Vulkan 1.3 or VK_KHR_dynamic_rendering)
};

class Buffer;
class ComputePipeline;

/// A loaded Vulkan loader, an instance, one device and one queue, with a command buffer, a fence,
/// a descriptor pool and a timestamp query pool for synchronous one-shot work. Every failure throws
/// VulkanError with a message naming what is missing or which call failed. Buffers and pipelines
/// made from a Context must be destroyed before it. Not thread-safe, except takeValidationMessages.
class Context {
  public:
    /// Creates and owns the instance and device. Where the device has it, dynamic rendering is
    /// enabled (the Vulkan 1.3 feature dynamicRendering, else VK_KHR_dynamic_rendering on 1.2);
    /// see dynamicRenderingEnabled().
    explicit Context(DeviceOptions options = {});
    /// Wraps the caller's instance, device and queue (nothing of theirs is created or destroyed;
    /// no validation messenger: the caller's instance reports). The Context creates only its own
    /// command pool, fence, descriptor pool and query pool on that device, and loads the functions
    /// through getInstanceProcAddr. VulkanError naming what is missing: a null handle or loader
    /// function, a device below Vulkan 1.2, a queue family out of range or without graphics and
    /// compute, a device function the driver does not provide. The features are what the caller
    /// says it enabled (enabledFeatures(), dynamicRenderingEnabled()); the renderers check those
    /// they need (tessellationShader, dynamicRendering, ...) when they are created.
    explicit Context(const ExternalDevice& device);
    /// Owned device: waits for the device to be idle, then destroys everything in reverse order
    /// of creation. Wrapped device (ExternalDevice): destroys only the Context's own objects.
    ~Context();
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;

    /// The names of the physical devices, in enumeration order (what DeviceOptions::device indexes).
    static std::vector<std::string> listDevices();

    /// The function table, for callers that record their own commands.
    const Functions& fn() const { return fn_; }
    const std::string& deviceName() const { return deviceName_; }
    /// A CPU implementation (lavapipe, SwiftShader): VK_PHYSICAL_DEVICE_TYPE_CPU.
    bool isSoftware() const { return properties_.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU; }
    VkInstance instance() const { return instance_; }
    VkPhysicalDevice physicalDevice() const { return physicalDevice_; }
    VkDevice device() const { return device_; }
    VkQueue queue() const { return queue_; }
    std::uint32_t queueFamily() const { return queueFamily_; }
    const VkPhysicalDeviceProperties& properties() const { return properties_; }
    /// The features enabled on the device (a subset of the supported ones).
    const VkPhysicalDeviceFeatures& enabledFeatures() const { return enabled_; }
    double timestampPeriodNs() const { return static_cast<double>(properties_.limits.timestampPeriod); }
    bool timestampsSupported() const { return timestampBits_ > 0; }
    bool float64Enabled() const { return enabled_.shaderFloat64 == VK_TRUE; }
    bool validationEnabled() const { return messenger_ != VK_NULL_HANDLE; }
    /// vkCmdBeginRendering / vkCmdEndRendering are loaded in fn() (what the renderers draw with).
    bool dynamicRenderingEnabled() const { return dynamicRendering_; }
    /// Whether the Context wraps the caller's device (ExternalDevice).
    bool isExternal() const { return external_; }

    /// The validation messages recorded since the last call ("[error] <message>"), then clears them.
    std::vector<std::string> takeValidationMessages();

    /// The index of a memory type allowed by typeBits with all the flags; VulkanError if none.
    std::uint32_t findMemoryType(std::uint32_t typeBits, VkMemoryPropertyFlags flags) const;

    /// Records commands with record() into the context's command buffer, submits them and waits.
    /// Not reentrant. If record throws, nothing is submitted and the exception propagates.
    void submitAndWait(const std::function<void(VkCommandBuffer)>& record);

    /// Runs pipeline once over groups work groups with buffers[i] at binding i and push constants
    /// (pushBytes must equal the pipeline's push constant size), waits, and returns the GPU time of
    /// the dispatch in seconds (NaN without timestamps). Shader writes are visible to the host on
    /// return. ArgumentError for a wrong buffer count, a null or too large buffer, a push constant
    /// size mismatch, or groups above maxComputeWorkGroupCount.
    double dispatch(const ComputePipeline& pipeline, std::span<const Buffer* const> buffers,
                    glm::uvec3 groups, const void* push = nullptr, std::size_t pushBytes = 0);

  private:
    void create(const DeviceOptions& options);
    void adopt(const ExternalDevice& device);
    void loadDeviceFunctions();
    void createSubmitObjects();
    void destroy() noexcept;
    static VKAPI_ATTR VkBool32 VKAPI_CALL onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                    VkDebugUtilsMessageTypeFlagsEXT types,
                                                    const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                    void* self);

    void* library_ = nullptr;
    Functions fn_{};
    VkInstance instance_ = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
    VkPhysicalDevice physicalDevice_ = VK_NULL_HANDLE;
    VkPhysicalDeviceProperties properties_{};
    std::string deviceName_;
    VkPhysicalDeviceFeatures enabled_{};
    std::uint32_t queueFamily_ = 0;
    std::uint32_t timestampBits_ = 0;
    VkDevice device_ = VK_NULL_HANDLE;
    VkQueue queue_ = VK_NULL_HANDLE;
    VkCommandPool commandPool_ = VK_NULL_HANDLE;
    VkCommandBuffer commandBuffer_ = VK_NULL_HANDLE;
    VkFence fence_ = VK_NULL_HANDLE;
    VkDescriptorPool descriptorPool_ = VK_NULL_HANDLE;
    VkQueryPool queryPool_ = VK_NULL_HANDLE;
    bool dynamicRendering_ = false;
    bool external_ = false;

    std::mutex messagesMutex_;
    std::vector<std::string> messages_;
};

} // namespace dispmap::vulkan
