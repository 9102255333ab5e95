// The viewer's instance, surface and device (vk_app.h).
#include "vk_app.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <utility>

namespace viewer {

using dispmap::vulkan::VulkanError;

namespace {

template <class Pfn> void load(Pfn& slot, PFN_vkVoidFunction f, const char* name) {
    if (!f) throw VulkanError(std::string("Vulkan function ") + name + " not provided by the loader or driver");
    slot = reinterpret_cast<Pfn>(f);
}

std::string lowercase(std::string s) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

bool hasLayer(const Vk& vk, const char* name) {
    std::uint32_t n = 0;
    VIEWER_CHECK(vk.vkEnumerateInstanceLayerProperties(&n, nullptr));
    std::vector<VkLayerProperties> layers(n);
    VIEWER_CHECK(vk.vkEnumerateInstanceLayerProperties(&n, layers.data()));
    return std::any_of(layers.begin(), layers.begin() + n, [&](const VkLayerProperties& l) { return std::strcmp(l.layerName, name) == 0; });
}

bool hasDeviceExtension(const Vk& vk, VkPhysicalDevice pd, const char* name) {
    std::uint32_t n = 0;
    VIEWER_CHECK(vk.vkEnumerateDeviceExtensionProperties(pd, nullptr, &n, nullptr));
    std::vector<VkExtensionProperties> ext(n);
    VIEWER_CHECK(vk.vkEnumerateDeviceExtensionProperties(pd, nullptr, &n, ext.data()));
    return std::any_of(ext.begin(), ext.begin() + n, [&](const VkExtensionProperties& e) { return std::strcmp(e.extensionName, name) == 0; });
}

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

} // namespace

VulkanApp::VulkanApp(GLFWwindow* window, const AppOptions& options) {
    try {
        create(window, options);
    } catch (...) {
        destroy();
        throw;
    }
}

VulkanApp::~VulkanApp() { destroy(); }

void VulkanApp::create(GLFWwindow* window, const AppOptions& options) {
    // The loader GLFW opened (it found libvulkan.so.1 when glfwVulkanSupported() said yes).
    load(vk_.vkGetInstanceProcAddr, glfwGetInstanceProcAddress(VK_NULL_HANDLE, "vkGetInstanceProcAddr"), "vkGetInstanceProcAddr");
#define VIEWER_LOAD(name) load(vk_.name, vk_.vkGetInstanceProcAddr(VK_NULL_HANDLE, #name), #name);
    VIEWER_VK_GLOBAL(VIEWER_LOAD)
#undef VIEWER_LOAD

    // Instance: GLFW's surface extensions, plus the validation layer and debug utils.
    std::uint32_t glfwCount = 0;
    const char** glfwExtensions = glfwGetRequiredInstanceExtensions(&glfwCount);
    if (!glfwExtensions) throw VulkanError("GLFW found no Vulkan surface extensions for this window system");
    std::vector<const char*> extensions(glfwExtensions, glfwExtensions + glfwCount);
    std::vector<const char*> layers;
    if (options.validation) {
        if (!hasLayer(vk_, kValidationLayer))
            throw VulkanError(std::string("validation requested but ") + kValidationLayer + " is not installed (vulkan-validationlayers)");
        layers.push_back(kValidationLayer);
        extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    }
    VkDebugUtilsMessengerCreateInfoEXT messengerInfo{};
    messengerInfo.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
    messengerInfo.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    messengerInfo.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                                VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    messengerInfo.pfnUserCallback = &VulkanApp::onMessage;
    messengerInfo.pUserData = this;
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO, nullptr, "dispmap_viewer", 1, "dispmap", 1, VK_API_VERSION_1_3};
    VkInstanceCreateInfo ii{};
    ii.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
    ii.pNext = options.validation ? &messengerInfo : nullptr;
    ii.pApplicationInfo = &app;
    ii.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
    ii.ppEnabledLayerNames = layers.data();
    ii.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
    ii.ppEnabledExtensionNames = extensions.data();
    VIEWER_CHECK(vk_.vkCreateInstance(&ii, nullptr, &instance_));
#define VIEWER_LOAD(name) load(vk_.name, vk_.vkGetInstanceProcAddr(instance_, #name), #name);
    VIEWER_VK_INSTANCE(VIEWER_LOAD)
    if (options.validation) {
        VIEWER_VK_DEBUG(VIEWER_LOAD)
    }
#undef VIEWER_LOAD
    if (options.validation) VIEWER_CHECK(vk_.vkCreateDebugUtilsMessengerEXT(instance_, &messengerInfo, nullptr, &messenger_));
    VIEWER_CHECK(glfwCreateWindowSurface(instance_, window, nullptr, &surface_));

    // Physical device: DISPMAP_VK_DEVICE / --device (index or name substring), else lavapipe,
    // else the first; it must have tessellation shaders and a graphics+compute queue that presents.
    std::uint32_t n = 0;
    VIEWER_CHECK(vk_.vkEnumeratePhysicalDevices(instance_, &n, nullptr));
    std::vector<VkPhysicalDevice> devices(n);
    VIEWER_CHECK(vk_.vkEnumeratePhysicalDevices(instance_, &n, devices.data()));
    if (n == 0) throw VulkanError("no Vulkan physical device; install mesa-vulkan-drivers (lavapipe) or a GPU driver");
    std::string want = options.device;
    if (want.empty())
        if (const char* env = std::getenv("DISPMAP_VK_DEVICE")) want = env;
    std::string available, rejected;
    std::vector<std::pair<int, std::size_t>> ranked; // (rank, index): lower rank first
    for (std::size_t i = 0; i < devices.size(); ++i) {
        VkPhysicalDeviceProperties p{};
        vk_.vkGetPhysicalDeviceProperties(devices[i], &p);
        const std::string name = p.deviceName;
        available += (i ? ", " : "") + std::to_string(i) + ": " + name;
        int rank = 1;
        if (!want.empty()) {
            if (want == std::to_string(i) || lowercase(name).find(lowercase(want)) != std::string::npos) rank = 0;
            else continue;
        } else if (name.find("llvmpipe") != std::string::npos) {
            rank = 0;
        }
        ranked.emplace_back(rank, i);
    }
    std::stable_sort(ranked.begin(), ranked.end());
    for (const auto& [rank, i] : ranked) {
        VkPhysicalDevice pd = devices[i];
        VkPhysicalDeviceProperties p{};
        vk_.vkGetPhysicalDeviceProperties(pd, &p);
        VkPhysicalDeviceFeatures f{};
        vk_.vkGetPhysicalDeviceFeatures(pd, &f);
        const std::string name = p.deviceName;
        if (!f.tessellationShader) {
            rejected += "; " + name + ": no tessellation shaders";
            continue;
        }
        if (p.apiVersion < VK_API_VERSION_1_2) {
            rejected += "; " + name + ": Vulkan 1.2 needed";
            continue;
        }
        if (!hasDeviceExtension(vk_, pd, VK_KHR_SWAPCHAIN_EXTENSION_NAME)) {
            rejected += "; " + name + ": no VK_KHR_swapchain";
            continue;
        }
        const bool core13 = p.apiVersion >= VK_API_VERSION_1_3;
        if (!core13 && !hasDeviceExtension(vk_, pd, VK_KHR_DYNAMIC_RENDERING_EXTENSION_NAME)) {
            rejected += "; " + name + ": no dynamic rendering";
            continue;
        }
        std::uint32_t fc = 0;
        vk_.vkGetPhysicalDeviceQueueFamilyProperties(pd, &fc, nullptr);
        std::vector<VkQueueFamilyProperties> families(fc);
        vk_.vkGetPhysicalDeviceQueueFamilyProperties(pd, &fc, families.data());
        std::uint32_t family = fc;
        for (std::uint32_t q = 0; q < fc && family == fc; ++q) {
            VkBool32 present = VK_FALSE;
            VIEWER_CHECK(vk_.vkGetPhysicalDeviceSurfaceSupportKHR(pd, q, surface_, &present));
            const VkQueueFlags need = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
            if ((families[q].queueFlags & need) == need && present) family = q;
        }
        if (family == fc) {
            rejected += "; " + name + ": no graphics+compute queue that presents to the window";
            continue;
        }
        physicalDevice_ = pd;
        properties_ = p;
        deviceName_ = name;
        queueFamily_ = family;
        // The renderer's features: tessellation, the wireframe's line fill and its independent
        // blend (colour written, normal target kept), statistics queries where there are any.
        enabled_.tessellationShader = VK_TRUE;
        enabled_.fillModeNonSolid = f.fillModeNonSolid;
        enabled_.independentBlend = f.independentBlend;
        enabled_.pipelineStatisticsQuery = f.pipelineStatisticsQuery;
        // The renderer's tessellation shader modules declare its (optional) vertex capture buffer
        // writable, so the validation layer asks for this feature even with capture off
        // (VUID-RuntimeSpirv-NonWritable-06341); dispmap's own Context enables it too.
        enabled_.vertexPipelineStoresAndAtomics = f.vertexPipelineStoresAndAtomics;
        break;
    }
    if (!physicalDevice_)
        throw VulkanError("no usable Vulkan device" + (want.empty() ? std::string() : " matching '" + want + "'") + " (available: " +
                          available + rejected + ")");

    // Device: the queue, the swapchain and dynamic rendering.
    const bool core13 = properties_.apiVersion >= VK_API_VERSION_1_3;
    std::vector<const char*> deviceExtensions{VK_KHR_SWAPCHAIN_EXTENSION_NAME};
    if (!core13) deviceExtensions.push_back(VK_KHR_DYNAMIC_RENDERING_EXTENSION_NAME);
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo qi{};
    qi.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
    qi.queueFamilyIndex = queueFamily_;
    qi.queueCount = 1;
    qi.pQueuePriorities = &priority;
    VkPhysicalDeviceDynamicRenderingFeatures dynamicRendering{};
    dynamicRendering.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DYNAMIC_RENDERING_FEATURES;
    dynamicRendering.dynamicRendering = VK_TRUE;
    VkDeviceCreateInfo di{};
    di.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
    di.pNext = &dynamicRendering;
    di.queueCreateInfoCount = 1;
    di.pQueueCreateInfos = &qi;
    di.enabledExtensionCount = static_cast<std::uint32_t>(deviceExtensions.size());
    di.ppEnabledExtensionNames = deviceExtensions.data();
    di.pEnabledFeatures = &enabled_;
    VIEWER_CHECK(vk_.vkCreateDevice(physicalDevice_, &di, nullptr, &device_));
#define VIEWER_LOAD(name) load(vk_.name, vk_.vkGetDeviceProcAddr(device_, #name), #name);
    VIEWER_VK_DEVICE(VIEWER_LOAD)
#undef VIEWER_LOAD
    load(vk_.vkCmdBeginRendering, vk_.vkGetDeviceProcAddr(device_, core13 ? "vkCmdBeginRendering" : "vkCmdBeginRenderingKHR"),
         "vkCmdBeginRendering");
    load(vk_.vkCmdEndRendering, vk_.vkGetDeviceProcAddr(device_, core13 ? "vkCmdEndRendering" : "vkCmdEndRenderingKHR"),
         "vkCmdEndRendering");
    vk_.vkGetDeviceQueue(device_, queueFamily_, 0, &queue_);
}

void VulkanApp::destroy() noexcept {
    if (device_) {
        vk_.vkDeviceWaitIdle(device_);
        vk_.vkDestroyDevice(device_, nullptr);
    }
    if (surface_) vk_.vkDestroySurfaceKHR(instance_, surface_, nullptr);
    if (messenger_) vk_.vkDestroyDebugUtilsMessengerEXT(instance_, messenger_, nullptr);
    if (instance_) vk_.vkDestroyInstance(instance_, nullptr);
    device_ = VK_NULL_HANDLE;
    surface_ = VK_NULL_HANDLE;
    messenger_ = VK_NULL_HANDLE;
    instance_ = VK_NULL_HANDLE;
}

dispmap::vulkan::ExternalDevice VulkanApp::external() const {
    dispmap::vulkan::ExternalDevice e{};
    e.getInstanceProcAddr = vk_.vkGetInstanceProcAddr;
    e.instance = instance_;
    e.physicalDevice = physicalDevice_;
    e.device = device_;
    e.queue = queue_;
    e.queueFamily = queueFamily_;
    e.enabledFeatures = enabled_;
    e.dynamicRendering = true;
    return e;
}

std::uint32_t VulkanApp::memoryType(std::uint32_t typeBits, VkMemoryPropertyFlags flags) const {
    VkPhysicalDeviceMemoryProperties m{};
    vk_.vkGetPhysicalDeviceMemoryProperties(physicalDevice_, &m);
    for (std::uint32_t i = 0; i < m.memoryTypeCount; ++i)
        if ((typeBits & (1u << i)) && (m.memoryTypes[i].propertyFlags & flags) == flags) return i;
    throw VulkanError("no memory type with flags " + std::to_string(flags));
}

std::vector<std::string> VulkanApp::takeMessages() {
    const std::lock_guard lock(messagesMutex_);
    return std::exchange(messages_, {});
}

VKAPI_ATTR VkBool32 VKAPI_CALL VulkanApp::onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT,
                                                    const VkDebugUtilsMessengerCallbackDataEXT* data, void* self) {
    auto* app = static_cast<VulkanApp*>(self);
    std::string m = severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "[error] " : "[warning] ";
    m += data && data->pMessage ? data->pMessage : "(no message)";
    const std::lock_guard lock(app->messagesMutex_);
    app->messages_.push_back(std::move(m));
    return VK_FALSE;
}

} // namespace viewer
