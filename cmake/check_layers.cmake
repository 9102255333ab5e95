# The layers of include/dispmap/ (and the Vulkan backend's headers): a header includes only
# headers of its own layer and of the layers below it, and no third-party header outside its
# layer's dependencies. Run as a test: cmake -DSOURCE_DIR=<repo> -P cmake/check_layers.cmake
#
# layer     may include dispmap/...              and third-party headers
# kernels   kernels                              glm
# core      kernels core                         glm, tbb, sys/mman.h (Linux, core/memory.h)
# meso      kernels core meso                    glm, tbb
# surface   kernels core surface                 glm, opensubdiv, tinyobjloader
# io        kernels core meso io                 glm, png, zlib, OpenEXR, Imath, tiffio.h
# scene     kernels core meso surface io scene   glm, nlohmann
# vulkan    kernels core meso surface vulkan     glm, vulkan
# bake      kernels core meso surface io bake    glm, opensubdiv, tinyobjloader, nlohmann, embree3, tbb,
#                                                assimp, meshoptimizer, nanoflann, sys/resource.h
# A standard header is one without a '.' or a '/' in its name (<vector>, <cmath>).
cmake_minimum_required(VERSION 3.25)
set(allowed_kernels kernels)
set(allowed_core kernels core)
set(allowed_meso kernels core meso)
set(allowed_surface kernels core surface)
set(allowed_io kernels core meso io)
set(allowed_scene kernels core meso surface io scene)
set(allowed_vulkan kernels core meso surface vulkan)
set(allowed_bake kernels core meso surface io bake)
set(third_kernels "^glm/")
set(third_core "^(glm|tbb)/|^sys/mman\\.h$")
set(third_meso "^(glm|tbb)/")
set(third_surface "^(glm|opensubdiv)/|^tiny_obj_loader\\.h$")
set(third_io "^(glm|OpenEXR|Imath)/|^(png|zlib|tiffio)\\.h$")
set(third_scene "^(glm|nlohmann)/")
set(third_vulkan "^(glm|vulkan)/")
set(third_bake "^(glm|opensubdiv|nlohmann|embree3|tbb|assimp)/|^(tiny_obj_loader\\.h|meshoptimizer\\.h|nanoflann\\.hpp|sys/resource\\.h)$")

set(failures 0)
set(checked 0)
file(GLOB_RECURSE headers RELATIVE ${SOURCE_DIR} ${SOURCE_DIR}/include/dispmap/*.h ${SOURCE_DIR}/backend_vulkan/include/dispmap/*.h)
foreach(rel IN LISTS headers)
  if(NOT rel MATCHES "dispmap/([a-z_]+)/[^/]+\\.h$")
    message(NOTICE "error: ${rel}: a public header outside every layer folder")
    math(EXPR failures "${failures} + 1")
    continue()
  endif()
  set(layer ${CMAKE_MATCH_1})
  if(NOT DEFINED allowed_${layer})
    message(NOTICE "error: ${rel}: unknown layer '${layer}' (add it to cmake/check_layers.cmake)")
    math(EXPR failures "${failures} + 1")
    continue()
  endif()
  math(EXPR checked "${checked} + 1")
  file(STRINGS ${SOURCE_DIR}/${rel} lines REGEX "^[ \t]*#[ \t]*include")
  foreach(line IN LISTS lines)
    if(line MATCHES "#[ \t]*include[ \t]*[\"<]dispmap/([a-z_]+)/[^\">]+[\">]")
      set(to ${CMAKE_MATCH_1})
      if(NOT to IN_LIST allowed_${layer})
        message(NOTICE "error: ${rel}: layer '${layer}' includes from layer '${to}': ${line}")
        math(EXPR failures "${failures} + 1")
      endif()
    elseif(line MATCHES "#[ \t]*include[ \t]*\"dispmap/")
      message(NOTICE "error: ${rel}: include outside every layer folder: ${line}")
      math(EXPR failures "${failures} + 1")
    elseif(line MATCHES "#[ \t]*include[ \t]*[\"<]([^\">]+)[\">]")
      set(name ${CMAKE_MATCH_1})
      if(NOT name MATCHES "^[a-z_0-9]+$" AND NOT name MATCHES "${third_${layer}}")
        message(NOTICE "error: ${rel}: layer '${layer}' includes '${name}', outside its dependencies")
        math(EXPR failures "${failures} + 1")
      endif()
    endif()
  endforeach()
endforeach()
if(checked EQUAL 0)
  message(FATAL_ERROR "no headers found under ${SOURCE_DIR}")
endif()
if(failures GREATER 0)
  message(FATAL_ERROR "${failures} layering violation(s) in ${checked} headers")
endif()
message(STATUS "layers: ${checked} headers, every include within its layer's reach")
