// The Vulkan Context: loader (dlopen), function table, instance with optional validation, device
// selection, device and queue, and the objects for one-shot submissions.
#include "dispmap/vulkan/context.h"

#include <dlfcn.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "dispmap/vulkan/compute.h"

namespace dispmap::vulkan {

const char* resultName(VkResult result) {
    switch (result) {
#define DISPMAP_VK_RESULT(name)                                                                              \
    case name:                                                                                               \
        return #name;
        DISPMAP_VK_RESULT(VK_SUCCESS)
        DISPMAP_VK_RESULT(VK_NOT_READY)
        DISPMAP_VK_RESULT(VK_TIMEOUT)
        DISPMAP_VK_RESULT(VK_EVENT_SET)
        DISPMAP_VK_RESULT(VK_EVENT_RESET)
        DISPMAP_VK_RESULT(VK_INCOMPLETE)
        DISPMAP_VK_RESULT(VK_ERROR_OUT_OF_HOST_MEMORY)
        DISPMAP_VK_RESULT(VK_ERROR_OUT_OF_DEVICE_MEMORY)
        DISPMAP_VK_RESULT(VK_ERROR_INITIALIZATION_FAILED)
        DISPMAP_VK_RESULT(VK_ERROR_DEVICE_LOST)
        DISPMAP_VK_RESULT(VK_ERROR_MEMORY_MAP_FAILED)
        DISPMAP_VK_RESULT(VK_ERROR_LAYER_NOT_PRESENT)
        DISPMAP_VK_RESULT(VK_ERROR_EXTENSION_NOT_PRESENT)
        DISPMAP_VK_RESULT(VK_ERROR_FEATURE_NOT_PRESENT)
        DISPMAP_VK_RESULT(VK_ERROR_INCOMPATIBLE_DRIVER)
        DISPMAP_VK_RESULT(VK_ERROR_TOO_MANY_OBJECTS)
        DISPMAP_VK_RESULT(VK_ERROR_FORMAT_NOT_SUPPORTED)
        DISPMAP_VK_RESULT(VK_ERROR_FRAGMENTED_POOL)
        DISPMAP_VK_RESULT(VK_ERROR_UNKNOWN)
        DISPMAP_VK_RESULT(VK_ERROR_OUT_OF_POOL_MEMORY)
        DISPMAP_VK_RESULT(VK_ERROR_INVALID_EXTERNAL_HANDLE)
        DISPMAP_VK_RESULT(VK_ERROR_FRAGMENTATION)
        DISPMAP_VK_RESULT(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS)
        DISPMAP_VK_RESULT(VK_PIPELINE_COMPILE_REQUIRED)
        DISPMAP_VK_RESULT(VK_ERROR_SURFACE_LOST_KHR)
        DISPMAP_VK_RESULT(VK_ERROR_NATIVE_WINDOW_IN_USE_KHR)
        DISPMAP_VK_RESULT(VK_SUBOPTIMAL_KHR)
        DISPMAP_VK_RESULT(VK_ERROR_OUT_OF_DATE_KHR)
        DISPMAP_VK_RESULT(VK_ERROR_VALIDATION_FAILED_EXT)
#undef DISPMAP_VK_RESULT
    default:
        return "VkResult(unknown)";
    }
}

void check(VkResult result, const char* call) {
    if (result == VK_SUCCESS) return;
    std::string name = resultName(result);
    if (name == "VkResult(unknown)") name = "VkResult(" + std::to_string(static_cast<int>(result)) + ")";
    throw VulkanError(std::string(call) + " failed: " + name);
}

namespace {

std::string envString(const char* name) {
    const char* value = std::getenv(name);
    return value ? value : "";
}

std::string lowercase(std::string s) {
    for (char& c : s)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

template <class Pfn> void setFunction(Pfn& slot, PFN_vkVoidFunction f, const char* name) {
    if (!f)
        throw VulkanError(std::string("Vulkan function ") + name + " not provided by the loader or driver");
    slot = reinterpret_cast<Pfn>(f);
}

/// dlopen()s the loader (DISPMAP_VULKAN_LIBRARY or libvulkan.so.1) and loads the global functions.
void* openLoader(Functions& fn) {
    std::string path = envString("DISPMAP_VULKAN_LIBRARY");
    if (path.empty()) path = "libvulkan.so.1";
    void* library = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        const char* error = dlerror();
        std::string why = error ? error : "unknown error";
        if (why.rfind(path, 0) != 0) why = path + ": " + why; // dlerror() usually names the path
        throw VulkanError("Vulkan loader not found (" + why +
                          "); install libvulkan1 and a driver such as mesa-vulkan-drivers");
    }
    void* symbol = dlsym(library, "vkGetInstanceProcAddr");
    if (!symbol) {
        dlclose(library);
        throw VulkanError("Vulkan loader " + path + " has no vkGetInstanceProcAddr");
    }
    fn.vkGetInstanceProcAddr = reinterpret_cast<PFN_vkGetInstanceProcAddr>(symbol);
    try {
#define DISPMAP_VK_LOAD(name) setFunction(fn.name, fn.vkGetInstanceProcAddr(VK_NULL_HANDLE, #name), #name);
        DISPMAP_VK_GLOBAL_FUNCTIONS(DISPMAP_VK_LOAD)
#undef DISPMAP_VK_LOAD
#define DISPMAP_VK_LOAD(name) fn.name = reinterpret_cast<PFN_##name>(fn.vkGetInstanceProcAddr(VK_NULL_HANDLE, #name));
        DISPMAP_VK_OPTIONAL_GLOBAL_FUNCTIONS(DISPMAP_VK_LOAD)
#undef DISPMAP_VK_LOAD
    } catch (...) {
        dlclose(library);
        throw;
    }
    return library;
}

void loadInstanceFunctions(Functions& fn, VkInstance instance, bool debug) {
#define DISPMAP_VK_LOAD(name) setFunction(fn.name, fn.vkGetInstanceProcAddr(instance, #name), #name);
    DISPMAP_VK_INSTANCE_FUNCTIONS(DISPMAP_VK_LOAD)
    if (debug) {
        DISPMAP_VK_DEBUG_FUNCTIONS(DISPMAP_VK_LOAD)
    }
#undef DISPMAP_VK_LOAD
}

/// The VulkanError for a failed vkCreateInstance, naming what is most likely missing.
VulkanError instanceError(VkResult result) {
    if (result == VK_ERROR_INCOMPATIBLE_DRIVER)
        return VulkanError(
            "no Vulkan device: the loader found no driver (vkCreateInstance failed: "
            "VK_ERROR_INCOMPATIBLE_DRIVER); install mesa-vulkan-drivers (lavapipe) or a GPU driver");
    return VulkanError(std::string("vkCreateInstance failed: ") + resultName(result));
}

std::vector<VkPhysicalDevice> physicalDevices(const Functions& fn, VkInstance instance) {
    std::uint32_t count = 0;
    DISPMAP_VK_CHECK(fn, vkEnumeratePhysicalDevices, instance, &count, nullptr);
    std::vector<VkPhysicalDevice> devices(count);
    if (count > 0) DISPMAP_VK_CHECK(fn, vkEnumeratePhysicalDevices, instance, &count, devices.data());
    devices.resize(count);
    if (devices.empty())
        throw VulkanError(
            "no Vulkan physical device found; install mesa-vulkan-drivers (lavapipe) or a GPU driver");
    return devices;
}

std::vector<std::string> deviceNames(const Functions& fn, const std::vector<VkPhysicalDevice>& devices) {
    std::vector<std::string> names;
    for (VkPhysicalDevice d : devices) {
        VkPhysicalDeviceProperties p{};
        fn.vkGetPhysicalDeviceProperties(d, &p);
        names.emplace_back(p.deviceName);
    }
    return names;
}

/// The index of the selected device (see DeviceOptions::device).
std::size_t selectDevice(const std::vector<std::string>& names, std::string selection) {
    const char* source = "DeviceOptions::device";
    if (selection.empty()) {
        selection = envString("DISPMAP_VK_DEVICE");
        source = "DISPMAP_VK_DEVICE";
    }
    if (selection.empty()) {
        for (std::size_t i = 0; i < names.size(); ++i)
            if (names[i].find("llvmpipe") != std::string::npos) return i;
        return 0;
    }
    const bool isIndex = std::all_of(selection.begin(), selection.end(),
                                     [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; });
    if (isIndex && selection.size() < 10) {
        const auto index = std::stoul(selection);
        if (index < names.size()) return index;
    } else if (!isIndex) {
        for (std::size_t i = 0; i < names.size(); ++i)
            if (lowercase(names[i]).find(lowercase(selection)) != std::string::npos) return i;
    }
    std::string available;
    for (std::size_t i = 0; i < names.size(); ++i)
        available += (i ? ", " : "") + std::to_string(i) + ": " + names[i];
    throw VulkanError(std::string("no Vulkan device matches ") + source + " '" + selection +
                      "' (an index or a name substring); available: " + available);
}

bool hasLayer(const Functions& fn, const char* layer) {
    std::uint32_t count = 0;
    DISPMAP_VK_CHECK(fn, vkEnumerateInstanceLayerProperties, &count, nullptr);
    std::vector<VkLayerProperties> layers(count);
    if (count > 0) DISPMAP_VK_CHECK(fn, vkEnumerateInstanceLayerProperties, &count, layers.data());
    layers.resize(count);
    return std::any_of(layers.begin(), layers.end(),
                       [&](const VkLayerProperties& l) { return std::strcmp(l.layerName, layer) == 0; });
}

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

bool hasDeviceExtension(const Functions& fn, VkPhysicalDevice device, const char* extension) {
    std::uint32_t count = 0;
    DISPMAP_VK_CHECK(fn, vkEnumerateDeviceExtensionProperties, device, nullptr, &count, nullptr);
    std::vector<VkExtensionProperties> extensions(count);
    if (count > 0) DISPMAP_VK_CHECK(fn, vkEnumerateDeviceExtensionProperties, device, nullptr, &count, extensions.data());
    extensions.resize(count);
    return std::any_of(extensions.begin(), extensions.end(),
                       [&](const VkExtensionProperties& e) { return std::strcmp(e.extensionName, extension) == 0; });
}

std::string versionString(std::uint32_t version) {
    return std::to_string(VK_API_VERSION_MAJOR(version)) + "." + std::to_string(VK_API_VERSION_MINOR(version));
}

} // namespace

Context::Context(DeviceOptions options) {
    try {
        create(options);
    } catch (...) {
        destroy();
        throw;
    }
}

Context::Context(const ExternalDevice& device) {
    try {
        adopt(device);
    } catch (...) {
        destroy();
        throw;
    }
}

Context::~Context() {
    destroy();
}

std::vector<std::string> Context::listDevices() {
    Functions fn{};
    void* library = openLoader(fn);
    VkInstance instance = VK_NULL_HANDLE;
    try {
        VkApplicationInfo app{
            VK_STRUCTURE_TYPE_APPLICATION_INFO, nullptr, "dispmap", 1, "dispmap", 1, VK_API_VERSION_1_2};
        VkInstanceCreateInfo info{};
        info.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
        info.pApplicationInfo = &app;
        const VkResult result = fn.vkCreateInstance(&info, nullptr, &instance);
        if (result != VK_SUCCESS) throw instanceError(result);
        loadInstanceFunctions(fn, instance, false);
        std::vector<std::string> names = deviceNames(fn, physicalDevices(fn, instance));
        fn.vkDestroyInstance(instance, nullptr);
        dlclose(library);
        return names;
    } catch (...) {
        if (instance && fn.vkDestroyInstance) fn.vkDestroyInstance(instance, nullptr);
        dlclose(library);
        throw;
    }
}

void Context::create(const DeviceOptions& options) {
    library_ = openLoader(fn_);

    // Instance, with the validation layer and a messenger that records warnings and errors.
    const std::string validationEnv = envString("DISPMAP_VK_VALIDATION");
    const bool validation = options.validation || (!validationEnv.empty() && validationEnv != "0");
    if (validation && !hasLayer(fn_, kValidationLayer))
        throw VulkanError(std::string("Vulkan validation requested but the layer ") + kValidationLayer +
                          " is not installed; install vulkan-validationlayers");
    VkDebugUtilsMessengerCreateInfoEXT messengerInfo{};
    messengerInfo.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
    messengerInfo.messageSeverity =
        VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    messengerInfo.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                                VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                                VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    messengerInfo.pfnUserCallback = &Context::onMessage;
    messengerInfo.pUserData = this;
    const char* layers[] = {kValidationLayer};
    const char* extensions[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME};
    // Vulkan 1.3 where the loader has it (dynamic rendering in core), else 1.2. The shaders stay
    // SPIR-V for Vulkan 1.2 (docs/lavapipe.md).
    std::uint32_t loaderVersion = VK_API_VERSION_1_0;
    if (fn_.vkEnumerateInstanceVersion) DISPMAP_VK_CHECK(fn_, vkEnumerateInstanceVersion, &loaderVersion);
    const std::uint32_t instanceVersion = loaderVersion >= VK_API_VERSION_1_3 ? VK_API_VERSION_1_3 : VK_API_VERSION_1_2;
    VkApplicationInfo app{
        VK_STRUCTURE_TYPE_APPLICATION_INFO, nullptr, "dispmap", 1, "dispmap", 1, instanceVersion};
    VkInstanceCreateInfo instanceInfo{};
    instanceInfo.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
    instanceInfo.pApplicationInfo = &app;
    if (validation) {
        instanceInfo.pNext = &messengerInfo; // also reports on vkCreateInstance and vkDestroyInstance
        instanceInfo.enabledLayerCount = 1;
        instanceInfo.ppEnabledLayerNames = layers;
        instanceInfo.enabledExtensionCount = 1;
        instanceInfo.ppEnabledExtensionNames = extensions;
    }
    const VkResult created = fn_.vkCreateInstance(&instanceInfo, nullptr, &instance_);
    if (created != VK_SUCCESS) {
        instance_ = VK_NULL_HANDLE;
        throw instanceError(created);
    }
    loadInstanceFunctions(fn_, instance_, validation);
    if (validation)
        DISPMAP_VK_CHECK(fn_, vkCreateDebugUtilsMessengerEXT, instance_, &messengerInfo, nullptr,
                         &messenger_);

    // Physical device, queue family and features.
    const std::vector<VkPhysicalDevice> devices = physicalDevices(fn_, instance_);
    physicalDevice_ = devices[selectDevice(deviceNames(fn_, devices), options.device)];
    fn_.vkGetPhysicalDeviceProperties(physicalDevice_, &properties_);
    deviceName_ = properties_.deviceName;
    if (properties_.apiVersion < VK_API_VERSION_1_2)
        throw VulkanError("Vulkan device '" + deviceName_ + "' supports only Vulkan " +
                          std::to_string(VK_API_VERSION_MAJOR(properties_.apiVersion)) + "." +
                          std::to_string(VK_API_VERSION_MINOR(properties_.apiVersion)) +
                          "; dispmap needs 1.2");

    std::uint32_t familyCount = 0;
    fn_.vkGetPhysicalDeviceQueueFamilyProperties(physicalDevice_, &familyCount, nullptr);
    std::vector<VkQueueFamilyProperties> families(familyCount);
    fn_.vkGetPhysicalDeviceQueueFamilyProperties(physicalDevice_, &familyCount, families.data());
    constexpr VkQueueFlags graphicsCompute = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
    std::uint32_t family = familyCount;
    for (std::uint32_t i = 0; i < familyCount && family == familyCount; ++i)
        if ((families[i].queueFlags & graphicsCompute) == graphicsCompute) family = i;
    for (std::uint32_t i = 0; i < familyCount && family == familyCount; ++i)
        if (families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) family = i;
    if (family == familyCount) throw VulkanError("Vulkan device '" + deviceName_ + "' has no compute queue");
    queueFamily_ = family;
    timestampBits_ = families[family].timestampValidBits;

    VkPhysicalDeviceFeatures supported{};
    fn_.vkGetPhysicalDeviceFeatures(physicalDevice_, &supported);
    if (options.float64 == Float64::Required && !supported.shaderFloat64)
        throw VulkanError("Vulkan device '" + deviceName_ +
                          "' does not support shaderFloat64 (double in shaders)");
    enabled_.shaderFloat64 = options.float64 != Float64::Off ? supported.shaderFloat64 : VK_FALSE;
    enabled_.tessellationShader = supported.tessellationShader;
    enabled_.fillModeNonSolid = supported.fillModeNonSolid;
    enabled_.pipelineStatisticsQuery = supported.pipelineStatisticsQuery;
    // The renderer's vertex capture (tests) writes from the tessellation evaluation shader.
    enabled_.vertexPipelineStoresAndAtomics = supported.vertexPipelineStoresAndAtomics;
    // The renderer's wireframe pass writes colour but leaves the normal target alone.
    enabled_.independentBlend = supported.independentBlend;

    // Dynamic rendering (what the renderers draw with): the 1.3 core feature, else the KHR
    // extension; neither: the Context still computes, the renderers refuse.
    const std::uint32_t deviceVersion = std::min(instanceVersion, properties_.apiVersion);
    VkPhysicalDeviceVulkan13Features features13{};
    features13.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES;
    VkPhysicalDeviceDynamicRenderingFeaturesKHR renderingKhr{};
    renderingKhr.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DYNAMIC_RENDERING_FEATURES_KHR;
    VkPhysicalDeviceFeatures2 query{};
    query.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
    const char* deviceExtensions[] = {VK_KHR_DYNAMIC_RENDERING_EXTENSION_NAME};
    void* deviceNext = nullptr;
    std::uint32_t deviceExtensionCount = 0;
    if (deviceVersion >= VK_API_VERSION_1_3) {
        query.pNext = &features13;
        fn_.vkGetPhysicalDeviceFeatures2(physicalDevice_, &query);
        if (features13.dynamicRendering) {
            features13 = {};
            features13.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES;
            features13.dynamicRendering = VK_TRUE;
            deviceNext = &features13;
            dynamicRendering_ = true;
        }
    } else if (hasDeviceExtension(fn_, physicalDevice_, VK_KHR_DYNAMIC_RENDERING_EXTENSION_NAME)) {
        query.pNext = &renderingKhr;
        fn_.vkGetPhysicalDeviceFeatures2(physicalDevice_, &query);
        if (renderingKhr.dynamicRendering) {
            renderingKhr = {};
            renderingKhr.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DYNAMIC_RENDERING_FEATURES_KHR;
            renderingKhr.dynamicRendering = VK_TRUE;
            deviceNext = &renderingKhr;
            deviceExtensionCount = 1;
            dynamicRendering_ = true;
        }
    }

    // Device, queue, and the objects of one-shot submissions.
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo queueInfo{};
    queueInfo.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
    queueInfo.queueFamilyIndex = queueFamily_;
    queueInfo.queueCount = 1;
    queueInfo.pQueuePriorities = &priority;
    VkDeviceCreateInfo deviceInfo{};
    deviceInfo.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
    deviceInfo.queueCreateInfoCount = 1;
    deviceInfo.pQueueCreateInfos = &queueInfo;
    deviceInfo.pEnabledFeatures = &enabled_;
    deviceInfo.pNext = deviceNext;
    deviceInfo.enabledExtensionCount = deviceExtensionCount;
    deviceInfo.ppEnabledExtensionNames = deviceExtensionCount ? deviceExtensions : nullptr;
    DISPMAP_VK_CHECK(fn_, vkCreateDevice, physicalDevice_, &deviceInfo, nullptr, &device_);
    loadDeviceFunctions();
    fn_.vkGetDeviceQueue(device_, queueFamily_, 0, &queue_);
    createSubmitObjects();
}

void Context::adopt(const ExternalDevice& d) {
    external_ = true;
    const char* missing = !d.getInstanceProcAddr ? "getInstanceProcAddr"
                          : !d.instance          ? "instance"
                          : !d.physicalDevice    ? "physicalDevice"
                          : !d.device            ? "device"
                          : !d.queue             ? "queue"
                                                 : nullptr;
    if (missing) throw VulkanError(std::string("ExternalDevice::") + missing + " is null");
    fn_.vkGetInstanceProcAddr = d.getInstanceProcAddr;
    instance_ = d.instance;
    loadInstanceFunctions(fn_, instance_, false);
    physicalDevice_ = d.physicalDevice;
    fn_.vkGetPhysicalDeviceProperties(physicalDevice_, &properties_);
    deviceName_ = properties_.deviceName;
    if (properties_.apiVersion < VK_API_VERSION_1_2)
        throw VulkanError("Vulkan device '" + deviceName_ + "' supports only Vulkan " + versionString(properties_.apiVersion) +
                          "; dispmap needs 1.2");
    std::uint32_t familyCount = 0;
    fn_.vkGetPhysicalDeviceQueueFamilyProperties(physicalDevice_, &familyCount, nullptr);
    std::vector<VkQueueFamilyProperties> families(familyCount);
    fn_.vkGetPhysicalDeviceQueueFamilyProperties(physicalDevice_, &familyCount, families.data());
    constexpr VkQueueFlags graphicsCompute = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
    if (d.queueFamily >= familyCount)
        throw VulkanError("ExternalDevice::queueFamily " + std::to_string(d.queueFamily) + " out of range: device '" +
                          deviceName_ + "' has " + std::to_string(familyCount) + " queue families");
    if ((families[d.queueFamily].queueFlags & graphicsCompute) != graphicsCompute)
        throw VulkanError("ExternalDevice::queueFamily " + std::to_string(d.queueFamily) + " of device '" + deviceName_ +
                          "' does not support both graphics and compute");
    queueFamily_ = d.queueFamily;
    timestampBits_ = families[d.queueFamily].timestampValidBits;
    enabled_ = d.enabledFeatures;
    dynamicRendering_ = d.dynamicRendering;
    device_ = d.device;
    queue_ = d.queue;
    loadDeviceFunctions();
    createSubmitObjects();
}

void Context::loadDeviceFunctions() {
#define DISPMAP_VK_LOAD(name) setFunction(fn_.name, fn_.vkGetDeviceProcAddr(device_, #name), #name);
    DISPMAP_VK_DEVICE_FUNCTIONS(DISPMAP_VK_LOAD)
#undef DISPMAP_VK_LOAD
    if (dynamicRendering_) {
        // The core name (Vulkan 1.3), else the extension's (VK_KHR_dynamic_rendering).
#define DISPMAP_VK_LOAD(name)                                                                                \
    {                                                                                                        \
        PFN_vkVoidFunction f = fn_.vkGetDeviceProcAddr(device_, #name);                                      \
        if (!f) f = fn_.vkGetDeviceProcAddr(device_, #name "KHR");                                           \
        setFunction(fn_.name, f, #name " (dynamic rendering)");                                              \
    }
        DISPMAP_VK_RENDERING_FUNCTIONS(DISPMAP_VK_LOAD)
#undef DISPMAP_VK_LOAD
    }
}

void Context::createSubmitObjects() {
    VkCommandPoolCreateInfo poolInfo{};
    poolInfo.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    poolInfo.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    poolInfo.queueFamilyIndex = queueFamily_;
    DISPMAP_VK_CHECK(fn_, vkCreateCommandPool, device_, &poolInfo, nullptr, &commandPool_);
    VkCommandBufferAllocateInfo bufferInfo{};
    bufferInfo.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    bufferInfo.commandPool = commandPool_;
    bufferInfo.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    bufferInfo.commandBufferCount = 1;
    DISPMAP_VK_CHECK(fn_, vkAllocateCommandBuffers, device_, &bufferInfo, &commandBuffer_);
    VkFenceCreateInfo fenceInfo{};
    fenceInfo.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    DISPMAP_VK_CHECK(fn_, vkCreateFence, device_, &fenceInfo, nullptr, &fence_);

    const VkDescriptorPoolSize poolSize{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                        ComputePipeline::kMaxStorageBuffers};
    VkDescriptorPoolCreateInfo descriptorInfo{};
    descriptorInfo.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
    descriptorInfo.maxSets = 1;
    descriptorInfo.poolSizeCount = 1;
    descriptorInfo.pPoolSizes = &poolSize;
    DISPMAP_VK_CHECK(fn_, vkCreateDescriptorPool, device_, &descriptorInfo, nullptr, &descriptorPool_);
    if (timestampsSupported()) {
        VkQueryPoolCreateInfo queryInfo{};
        queryInfo.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
        queryInfo.queryType = VK_QUERY_TYPE_TIMESTAMP;
        queryInfo.queryCount = 2;
        DISPMAP_VK_CHECK(fn_, vkCreateQueryPool, device_, &queryInfo, nullptr, &queryPool_);
    }
}

void Context::destroy() noexcept {
    // A wrapped device: only what the Context made. Its submissions were waited for (submitAndWait,
    // dispatch), so nothing of it is in use; the device is the caller's to wait for.
    // (A handle that is set implies the device functions were loaded.)
    if (device_) {
        if (!external_ && fn_.vkDeviceWaitIdle) fn_.vkDeviceWaitIdle(device_);
        if (queryPool_) fn_.vkDestroyQueryPool(device_, queryPool_, nullptr);
        if (descriptorPool_) fn_.vkDestroyDescriptorPool(device_, descriptorPool_, nullptr);
        if (fence_) fn_.vkDestroyFence(device_, fence_, nullptr);
        if (commandPool_) fn_.vkDestroyCommandPool(device_, commandPool_, nullptr);
        if (!external_ && fn_.vkDestroyDevice) fn_.vkDestroyDevice(device_, nullptr);
    }
    if (messenger_) fn_.vkDestroyDebugUtilsMessengerEXT(instance_, messenger_, nullptr);
    if (instance_ && !external_) fn_.vkDestroyInstance(instance_, nullptr);
    if (library_) dlclose(library_);
    queryPool_ = VK_NULL_HANDLE;
    descriptorPool_ = VK_NULL_HANDLE;
    fence_ = VK_NULL_HANDLE;
    commandPool_ = VK_NULL_HANDLE;
    device_ = VK_NULL_HANDLE;
    messenger_ = VK_NULL_HANDLE;
    instance_ = VK_NULL_HANDLE;
    library_ = nullptr;
}

VKAPI_ATTR VkBool32 VKAPI_CALL Context::onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                  VkDebugUtilsMessageTypeFlagsEXT /*types*/,
                                                  const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                  void* self) {
    auto* context = static_cast<Context*>(self);
    std::string message =
        severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "[error] " : "[warning] ";
    message += data && data->pMessage ? data->pMessage : "(no message)";
    const std::lock_guard lock(context->messagesMutex_);
    context->messages_.push_back(std::move(message));
    return VK_FALSE;
}

std::vector<std::string> Context::takeValidationMessages() {
    const std::lock_guard lock(messagesMutex_);
    return std::exchange(messages_, {});
}

std::uint32_t Context::findMemoryType(std::uint32_t typeBits, VkMemoryPropertyFlags flags) const {
    VkPhysicalDeviceMemoryProperties memory{};
    fn_.vkGetPhysicalDeviceMemoryProperties(physicalDevice_, &memory);
    for (std::uint32_t i = 0; i < memory.memoryTypeCount; ++i)
        if ((typeBits & (1u << i)) && (memory.memoryTypes[i].propertyFlags & flags) == flags) return i;
    throw VulkanError("Vulkan device '" + deviceName_ + "' has no memory type with property flags " +
                      std::to_string(flags) + " for this resource");
}

void Context::submitAndWait(const std::function<void(VkCommandBuffer)>& record) {
    VkCommandBufferBeginInfo begin{};
    begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    DISPMAP_VK_CHECK(fn_, vkBeginCommandBuffer, commandBuffer_, &begin);
    try {
        record(commandBuffer_);
    } catch (...) {
        fn_.vkResetCommandBuffer(commandBuffer_, 0);
        throw;
    }
    DISPMAP_VK_CHECK(fn_, vkEndCommandBuffer, commandBuffer_);
    VkSubmitInfo submit{};
    submit.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &commandBuffer_;
    DISPMAP_VK_CHECK(fn_, vkQueueSubmit, queue_, 1, &submit, fence_);
    DISPMAP_VK_CHECK(fn_, vkWaitForFences, device_, 1, &fence_, VK_TRUE, UINT64_MAX);
    DISPMAP_VK_CHECK(fn_, vkResetFences, device_, 1, &fence_);
}

} // namespace dispmap::vulkan
