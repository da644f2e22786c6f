#include "vk/context.hpp"

#include "error.hpp"
#include "vk/check.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <type_traits>

namespace hp::vk {

const char* result_name(VkResult r) {
  switch (r) {
#define HP_CASE(x) \
  case x: return #x;
    HP_CASE(VK_SUCCESS)
    HP_CASE(VK_NOT_READY)
    HP_CASE(VK_TIMEOUT)
    HP_CASE(VK_INCOMPLETE)
    HP_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
    HP_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    HP_CASE(VK_ERROR_INITIALIZATION_FAILED)
    HP_CASE(VK_ERROR_DEVICE_LOST)
    HP_CASE(VK_ERROR_MEMORY_MAP_FAILED)
    HP_CASE(VK_ERROR_LAYER_NOT_PRESENT)
    HP_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
    HP_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
    HP_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
    HP_CASE(VK_ERROR_TOO_MANY_OBJECTS)
    HP_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
#undef HP_CASE
    default: return "VkResult(unknown)";
  }
}

void fail(VkResult r, const char* call, const char* file, int line) {
  const char* base = std::strrchr(file, '/');
  std::string where = std::string(base ? base + 1 : file) + ":" + std::to_string(line);
  if (r == VK_ERROR_OUT_OF_DEVICE_MEMORY || r == VK_ERROR_OUT_OF_HOST_MEMORY || r == VK_ERROR_DEVICE_LOST ||
      r == VK_ERROR_FEATURE_NOT_PRESENT || r == VK_ERROR_EXTENSION_NOT_PRESENT) {
    throw DeviceError(std::string("Vulkan: ") + call + " returned " + result_name(r) + " (" + where + ")");
  }
  throw std::runtime_error(std::string("Vulkan: ") + call + " returned " + result_name(r) + " (" + where + ")");
}

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
constexpr const char* kNoDeviceHelp =
    "install Mesa's software Vulkan driver lavapipe (apt-get install mesa-vulkan-drivers, or run scripts/setup) "
    "or a GPU driver";

std::string device_type_name(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
    default: return "other";
  }
}

std::string version_string(uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
         std::to_string(VK_API_VERSION_PATCH(v));
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

}  // namespace

std::string driver_version_string(const std::string& driver_info, uint32_t vendor_id, uint32_t v) {
  if (driver_info.rfind("Mesa ", 0) == 0) {  // "Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)"
    const std::string rest = driver_info.substr(5);
    const std::string release = rest.substr(0, rest.find(' '));
    if (!release.empty()) return release;
  }
  if (vendor_id == 0x10DE) {  // NVIDIA packs major.minor.secondary.tertiary as 10.8.8.6 bits
    return std::to_string(v >> 22) + "." + std::to_string((v >> 14) & 0xFF) + "." + std::to_string((v >> 6) & 0xFF) +
           "." + std::to_string(v & 0x3F);
  }
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
         std::to_string(VK_API_VERSION_PATCH(v));
}

namespace {

bool has_extension(const std::vector<VkExtensionProperties>& all, const char* name) {
  return std::any_of(all.begin(), all.end(),
                     [&](const VkExtensionProperties& e) { return std::strcmp(e.extensionName, name) == 0; });
}

std::vector<VkExtensionProperties> device_extensions(VkPhysicalDevice pd) {
  uint32_t n = 0;
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &n, nullptr);
  std::vector<VkExtensionProperties> all(n);
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &n, all.data());
  all.resize(n);
  return all;
}

// Which of the driver's ray tracing the device offers with every feature hybridprof uses.
void describe_ray_tracing(VkPhysicalDevice pd, DeviceInfo& info) {
  const auto ext = device_extensions(pd);
  const bool as = has_extension(ext, VK_KHR_ACCELERATION_STRUCTURE_EXTENSION_NAME) &&
                  has_extension(ext, VK_KHR_DEFERRED_HOST_OPERATIONS_EXTENSION_NAME);
  if (!as) return;
  VkPhysicalDeviceRayQueryFeaturesKHR rq{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_QUERY_FEATURES_KHR};
  VkPhysicalDeviceRayTracingPipelineFeaturesKHR rtp{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR};
  rtp.pNext = &rq;
  VkPhysicalDeviceAccelerationStructureFeaturesKHR asf{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
  asf.pNext = &rtp;
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  f12.pNext = &asf;
  VkPhysicalDeviceFeatures2 f{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f.pNext = &f12;
  vkGetPhysicalDeviceFeatures2(pd, &f);
  if (!asf.accelerationStructure || !f12.bufferDeviceAddress) return;
  info.ray_query = has_extension(ext, VK_KHR_RAY_QUERY_EXTENSION_NAME) && rq.rayQuery;
  info.ray_tracing_pipeline = has_extension(ext, VK_KHR_RAY_TRACING_PIPELINE_EXTENSION_NAME) &&
                              rtp.rayTracingPipeline && rtp.rayTracingPipelineTraceRaysIndirect;
}

DeviceInfo describe(VkPhysicalDevice pd, const std::vector<VkQueueFamilyProperties>& families, uint32_t family) {
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDeviceSubgroupProperties subgroup{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
  subgroup.pNext = &driver;
  VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  p2.pNext = &subgroup;
  vkGetPhysicalDeviceProperties2(pd, &p2);
  const auto& p = p2.properties;
  DeviceInfo info;
  info.name = p.deviceName;
  info.type = device_type_name(p.deviceType);
  info.driver_name = driver.driverName;
  info.driver_info = driver.driverInfo;
  info.driver_version = driver_version_string(info.driver_info, p.vendorID, p.driverVersion);
  info.api_version = version_string(p.apiVersion);
  info.vendor_id = p.vendorID;
  info.device_id = p.deviceID;
  info.subgroup_size = subgroup.subgroupSize;
  const VkSubgroupFeatureFlags ballot = VK_SUBGROUP_FEATURE_BASIC_BIT | VK_SUBGROUP_FEATURE_BALLOT_BIT;
  info.subgroup_ballot_compute = (subgroup.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT) != 0 &&
                                 (subgroup.supportedOperations & ballot) == ballot;
  info.timestamp_period_ns = p.limits.timestampPeriod;
  info.timestamp_valid_bits = family < families.size() ? families[family].timestampValidBits : 0;
  info.max_storage_buffer_range = p.limits.maxStorageBufferRange;
  if (p.apiVersion >= VK_API_VERSION_1_2) describe_ray_tracing(pd, info);
  return info;
}

std::vector<VkQueueFamilyProperties> queue_families(VkPhysicalDevice pd) {
  uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, nullptr);
  std::vector<VkQueueFamilyProperties> f(n);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, f.data());
  return f;
}

// The first family that does graphics and compute (transfer is implied by either).
int pick_family(const std::vector<VkQueueFamilyProperties>& families) {
  for (uint32_t i = 0; i < families.size(); ++i) {
    const VkQueueFlags need = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
    if ((families[i].queueFlags & need) == need) return static_cast<int>(i);
  }
  return -1;
}

VkBool32 VKAPI_PTR on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT,
                              const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* log = static_cast<Context::MessageLog*>(user);
  if (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
    static std::mutex mutex;
    std::lock_guard<std::mutex> lock(mutex);
    log->count.fetch_add(1);
    log->last = data && data->pMessage ? data->pMessage : "(no message)";
    if (log->print) std::fprintf(stderr, "hybridprof: validation: %s\n", log->last.c_str());
  }
  return VK_FALSE;
}

struct InstanceHolder {
  VkInstance instance = VK_NULL_HANDLE;
  ~InstanceHolder() {
    if (instance) vkDestroyInstance(instance, nullptr);
  }
};

VkInstance create_instance(bool validate, Context::MessageLog* log, VkDebugUtilsMessengerEXT* messenger) {
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "hybridprof";
  app.apiVersion = VK_API_VERSION_1_3;
  VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &app;
  std::vector<const char*> layers, extensions;
  VkDebugUtilsMessengerCreateInfoEXT dci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  if (validate) {
    if (!validation_layer_available()) {
      throw DeviceError(std::string("--validate: ") + kValidationLayer +
                        " is not installed (apt-get install vulkan-validationlayers)");
    }
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    dci.messageSeverity =
        VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    dci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                      VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    dci.pfnUserCallback = on_message;
    dci.pUserData = log;
    ci.pNext = &dci;  // also reports problems during vkCreateInstance / vkDestroyInstance
  }
  ci.enabledLayerCount = static_cast<uint32_t>(layers.size());
  ci.ppEnabledLayerNames = layers.data();
  ci.enabledExtensionCount = static_cast<uint32_t>(extensions.size());
  ci.ppEnabledExtensionNames = extensions.data();
  VkInstance instance = VK_NULL_HANDLE;
  VkResult r = vkCreateInstance(&ci, nullptr, &instance);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER || r == VK_ERROR_INITIALIZATION_FAILED) {
    throw DeviceError(std::string("no Vulkan device: the loader found no driver (") + result_name(r) + "); " +
                      kNoDeviceHelp);
  }
  HP_VK(r);
  if (validate) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
    if (!create || create(instance, &dci, nullptr, messenger) != VK_SUCCESS) {
      vkDestroyInstance(instance, nullptr);
      throw DeviceError("--validate: could not create the debug messenger");
    }
  }
  return instance;
}

std::vector<VkPhysicalDevice> physical_devices(VkInstance instance) {
  uint32_t n = 0;
  HP_VK(vkEnumeratePhysicalDevices(instance, &n, nullptr));
  std::vector<VkPhysicalDevice> v(n);
  if (n) HP_VK(vkEnumeratePhysicalDevices(instance, &n, v.data()));
  return v;
}

}  // namespace

bool validation_layer_available() {
  uint32_t n = 0;
  if (vkEnumerateInstanceLayerProperties(&n, nullptr) != VK_SUCCESS) return false;
  std::vector<VkLayerProperties> layers(n);
  vkEnumerateInstanceLayerProperties(&n, layers.data());
  return std::any_of(layers.begin(), layers.end(),
                     [](const VkLayerProperties& l) { return std::strcmp(l.layerName, kValidationLayer) == 0; });
}

std::vector<DeviceInfo> list_devices() {
  Context::MessageLog log;
  VkDebugUtilsMessengerEXT unused = VK_NULL_HANDLE;
  InstanceHolder holder;
  holder.instance = create_instance(false, &log, &unused);
  std::vector<DeviceInfo> out;
  for (VkPhysicalDevice pd : physical_devices(holder.instance)) {
    auto families = queue_families(pd);
    int f = pick_family(families);
    out.push_back(describe(pd, families, f < 0 ? 0u : static_cast<uint32_t>(f)));
  }
  return out;
}

Context::Context(const ContextOptions& options) {
  messages_->print = options.print_messages;
  instance_ = create_instance(options.validate, messages_.get(), &messenger_);
  try {
    std::vector<VkPhysicalDevice> devices = physical_devices(instance_);
    if (devices.empty()) throw DeviceError(std::string("no Vulkan device found; ") + kNoDeviceHelp);

    std::vector<DeviceInfo> infos;
    for (VkPhysicalDevice pd : devices) {
      auto families = queue_families(pd);
      int f = pick_family(families);
      infos.push_back(describe(pd, families, f < 0 ? 0u : static_cast<uint32_t>(f)));
    }
    int chosen = -1;
    const std::string& want = options.device;
    if (want.empty()) {
      for (size_t i = 0; i < infos.size() && chosen < 0; ++i)
        if (infos[i].type == "discrete") chosen = static_cast<int>(i);
      for (size_t i = 0; i < infos.size() && chosen < 0; ++i)
        if (lower(infos[i].name).find("llvmpipe") != std::string::npos) chosen = static_cast<int>(i);
      if (chosen < 0) chosen = 0;
    } else if (std::all_of(want.begin(), want.end(), [](unsigned char c) { return std::isdigit(c); })) {
      size_t idx = std::stoul(want);
      if (idx >= infos.size()) {
        throw DeviceError("--device " + want + ": only " + std::to_string(infos.size()) +
                          " Vulkan device(s) (indices 0.." + std::to_string(infos.size() - 1) + ")");
      }
      chosen = static_cast<int>(idx);
    } else {
      for (size_t i = 0; i < infos.size() && chosen < 0; ++i)
        if (lower(infos[i].name).find(lower(want)) != std::string::npos) chosen = static_cast<int>(i);
      if (chosen < 0) {
        std::string names;
        for (const auto& i : infos) names += (names.empty() ? "" : ", ") + i.name;
        throw DeviceError("--device '" + want + "' matches no Vulkan device (found: " + names + ")");
      }
    }
    physical_ = devices[chosen];
    info_ = infos[chosen];
    vkGetPhysicalDeviceProperties(physical_, &props_);
    vkGetPhysicalDeviceMemoryProperties(physical_, &mem_props_);
    auto families = queue_families(physical_);
    int family = pick_family(families);
    if (family < 0) throw DeviceError("Vulkan device '" + info_.name + "' has no graphics+compute queue");
    queue_family_ = static_cast<uint32_t>(family);
    if (props_.apiVersion < VK_API_VERSION_1_3) {
      throw DeviceError("Vulkan device '" + info_.name + "' supports Vulkan " + info_.api_version +
                        "; hybridprof needs 1.3 (dynamic rendering, synchronization2)");
    }

    VkPhysicalDeviceVulkan13Features f13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
    VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    f12.pNext = &f13;
    VkPhysicalDeviceFeatures2 supported{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    supported.pNext = &f12;
    vkGetPhysicalDeviceFeatures2(physical_, &supported);
    if (!f13.dynamicRendering || !f13.synchronization2) {
      throw DeviceError("Vulkan device '" + info_.name + "' lacks dynamicRendering or synchronization2");
    }
    // The watertight triangle test recomputes edge functions in double on exact zeros (Woop et al. 2013).
    if (!supported.features.shaderFloat64) {
      throw DeviceError("Vulkan device '" + info_.name +
                        "' lacks shaderFloat64 (the watertight ray/triangle test needs it)");
    }
    VkPhysicalDeviceVulkan13Features e13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
    e13.dynamicRendering = VK_TRUE;
    e13.synchronization2 = VK_TRUE;
    VkPhysicalDeviceVulkan12Features e12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    e12.pNext = &e13;
    e12.hostQueryReset = f12.hostQueryReset;
    e12.scalarBlockLayout = f12.scalarBlockLayout;
    VkPhysicalDeviceFeatures2 enabled{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    enabled.pNext = &e12;
    enabled.features.pipelineStatisticsQuery = supported.features.pipelineStatisticsQuery;
    enabled.features.shaderInt64 = supported.features.shaderInt64;
    enabled.features.shaderFloat64 = VK_TRUE;
    enabled.features.fragmentStoresAndAtomics = supported.features.fragmentStoresAndAtomics;

    // The driver's ray tracing, where the device has it: acceleration structures, buffer device addresses,
    // ray queries and ray-tracing pipelines (--traversal ray-query|pipeline).
    std::vector<const char*> extensions;
    VkPhysicalDeviceAccelerationStructureFeaturesKHR eas{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
    VkPhysicalDeviceRayQueryFeaturesKHR erq{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_QUERY_FEATURES_KHR};
    VkPhysicalDeviceRayTracingPipelineFeaturesKHR ertp{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR};
    if (info_.ray_query || info_.ray_tracing_pipeline) {
      extensions.push_back(VK_KHR_ACCELERATION_STRUCTURE_EXTENSION_NAME);
      extensions.push_back(VK_KHR_DEFERRED_HOST_OPERATIONS_EXTENSION_NAME);
      e12.bufferDeviceAddress = VK_TRUE;
      eas.accelerationStructure = VK_TRUE;
      eas.pNext = e12.pNext;
      e12.pNext = &eas;
      if (info_.ray_query) {
        extensions.push_back(VK_KHR_RAY_QUERY_EXTENSION_NAME);
        erq.rayQuery = VK_TRUE;
        erq.pNext = e12.pNext;
        e12.pNext = &erq;
      }
      if (info_.ray_tracing_pipeline) {
        extensions.push_back(VK_KHR_RAY_TRACING_PIPELINE_EXTENSION_NAME);
        ertp.rayTracingPipeline = VK_TRUE;
        ertp.rayTracingPipelineTraceRaysIndirect = VK_TRUE;
        ertp.pNext = e12.pNext;
        e12.pNext = &ertp;
      }
    }

    float priority = 1.0f;
    VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qci.queueFamilyIndex = queue_family_;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    dci.pNext = &enabled;
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    dci.enabledExtensionCount = uint32_t(extensions.size());
    dci.ppEnabledExtensionNames = extensions.data();
    HP_VK(vkCreateDevice(physical_, &dci, nullptr, &device_));
    if (info_.ray_query || info_.ray_tracing_pipeline) {
      const auto load = [&](auto& fn, const char* name) {
        fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(vkGetDeviceProcAddr(device_, name));
        if (!fn) throw DeviceError(std::string("Vulkan device '") + info_.name + "' does not provide " + name);
      };
      load(rt_.get_build_sizes, "vkGetAccelerationStructureBuildSizesKHR");
      load(rt_.create_as, "vkCreateAccelerationStructureKHR");
      load(rt_.destroy_as, "vkDestroyAccelerationStructureKHR");
      load(rt_.cmd_build, "vkCmdBuildAccelerationStructuresKHR");
      load(rt_.cmd_copy, "vkCmdCopyAccelerationStructureKHR");
      load(rt_.cmd_write_properties, "vkCmdWriteAccelerationStructuresPropertiesKHR");
      load(rt_.get_as_address, "vkGetAccelerationStructureDeviceAddressKHR");
      if (info_.ray_tracing_pipeline) {
        load(rt_.create_pipelines, "vkCreateRayTracingPipelinesKHR");
        load(rt_.get_group_handles, "vkGetRayTracingShaderGroupHandlesKHR");
        load(rt_.cmd_trace_rays, "vkCmdTraceRaysKHR");
        load(rt_.cmd_trace_rays_indirect, "vkCmdTraceRaysIndirectKHR");
        rt_props_ = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR};
        VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
        p2.pNext = &rt_props_;
        vkGetPhysicalDeviceProperties2(physical_, &p2);
      }
    }
    vkGetDeviceQueue(device_, queue_family_, 0, &queue_);

    VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pci.queueFamilyIndex = queue_family_;
    HP_VK(vkCreateCommandPool(device_, &pci, nullptr, &pool_));
    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    HP_VK(vkCreateFence(device_, &fci, nullptr, &fence_));
  } catch (...) {
    release();  // members are destroyed by unwinding, handles are not
    throw;
  }
}

Context::~Context() { release(); }

void Context::release() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    if (fence_) vkDestroyFence(device_, fence_, nullptr);
    if (pool_) vkDestroyCommandPool(device_, pool_, nullptr);
    vkDestroyDevice(device_, nullptr);
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
  device_ = VK_NULL_HANDLE;
  messenger_ = VK_NULL_HANDLE;
  instance_ = VK_NULL_HANDLE;
  fence_ = VK_NULL_HANDLE;
  pool_ = VK_NULL_HANDLE;
}

std::string Context::last_validation_message() const { return messages_->last; }

uint32_t Context::find_memory_type(uint32_t type_bits, VkMemoryPropertyFlags required) const {
  for (uint32_t i = 0; i < mem_props_.memoryTypeCount; ++i) {
    if ((type_bits & (1u << i)) && (mem_props_.memoryTypes[i].propertyFlags & required) == required) return i;
  }
  throw DeviceError("Vulkan device '" + info_.name + "' has no memory type with flags " + std::to_string(required));
}

VkCommandBuffer Context::begin_one_shot() {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  HP_VK(vkAllocateCommandBuffers(device_, &ai, &cmd));
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  HP_VK(vkBeginCommandBuffer(cmd, &bi));
  return cmd;
}

void Context::end_one_shot(VkCommandBuffer cmd) {
  HP_VK(vkEndCommandBuffer(cmd));
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  HP_VK(vkResetFences(device_, 1, &fence_));
  HP_VK(vkQueueSubmit(queue_, 1, &si, fence_));
  HP_VK(vkWaitForFences(device_, 1, &fence_, VK_TRUE, UINT64_MAX));
  vkFreeCommandBuffers(device_, pool_, 1, &cmd);
}

}  // namespace hp::vk
