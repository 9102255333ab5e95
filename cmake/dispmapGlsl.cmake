# GLSL → SPIR-V at build time with glslangValidator (glslang-tools).
#
# dispmap_spirv_header(<target> SOURCE <file.comp|.vert|...> NAME <c identifier>
#                      [INCLUDE_DIRS dir...] [DEFINES NAME[=value]...] [DEPENDS file...])
#   Compiles SOURCE for Vulkan 1.2 (lavapipe: 1.3 would give compute shaders LocalSizeId,
#   which needs maintenance4) and writes ${CMAKE_CURRENT_BINARY_DIR}/spirv/<NAME>.h holding
#   `const uint32_t <NAME>[]`; adds that folder to <target>'s include path and makes the
#   target depend on it. Edited includes recompile through glslang's depfile.
#
# dispmap_glsl_check(<target> SOURCE <file> [INCLUDE_DIRS ...] [DEFINES ...] [DEPENDS ...])
#   Compiles SOURCE to a throwaway .spv as part of <target> (a custom target): the build fails
#   on any glslang error. Used for every generated kernel include.
find_program(DISPMAP_GLSLANG glslangValidator)
if(NOT DISPMAP_GLSLANG)
  message(FATAL_ERROR "glslangValidator not found: run cmake/setup-debian.sh (package glslang-tools)")
endif()

function(_dispmap_glslang_command out_var source spv depfile)
  cmake_parse_arguments(PARSE_ARGV 4 A "" "" "INCLUDE_DIRS;DEFINES;EXTRA")
  set(cmd ${DISPMAP_GLSLANG} --quiet --target-env vulkan1.2)
  foreach(d IN LISTS A_INCLUDE_DIRS)
    list(APPEND cmd "-I${d}")
  endforeach()
  foreach(d IN LISTS A_DEFINES)
    list(APPEND cmd "-D${d}")
  endforeach()
  list(APPEND cmd ${A_EXTRA} --depfile ${depfile} -o ${spv} ${source})
  set(${out_var} ${cmd} PARENT_SCOPE)
endfunction()

function(dispmap_spirv_header target)
  cmake_parse_arguments(PARSE_ARGV 1 A "" "SOURCE;NAME" "INCLUDE_DIRS;DEFINES;DEPENDS")
  get_filename_component(src ${A_SOURCE} ABSOLUTE)
  set(dir ${CMAKE_CURRENT_BINARY_DIR}/spirv)
  set(header ${dir}/${A_NAME}.h)
  _dispmap_glslang_command(cmd ${src} ${header} ${dir}/${A_NAME}.d
    INCLUDE_DIRS ${A_INCLUDE_DIRS} DEFINES ${A_DEFINES} EXTRA --vn ${A_NAME})
  add_custom_command(OUTPUT ${header}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${dir}
    COMMAND ${cmd}
    MAIN_DEPENDENCY ${src}
    DEPENDS ${A_DEPENDS}
    DEPFILE ${dir}/${A_NAME}.d
    COMMENT "glslang ${A_NAME}"
    VERBATIM)
  target_sources(${target} PRIVATE ${header})
  target_include_directories(${target} PRIVATE ${dir})
endfunction()

function(dispmap_glsl_check target)
  cmake_parse_arguments(PARSE_ARGV 1 A "" "SOURCE;NAME" "INCLUDE_DIRS;DEFINES;DEPENDS")
  get_filename_component(src ${A_SOURCE} ABSOLUTE)
  set(dir ${CMAKE_CURRENT_BINARY_DIR}/glsl-check)
  set(spv ${dir}/${A_NAME}.spv)
  _dispmap_glslang_command(cmd ${src} ${spv} ${dir}/${A_NAME}.d
    INCLUDE_DIRS ${A_INCLUDE_DIRS} DEFINES ${A_DEFINES})
  add_custom_command(OUTPUT ${spv}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${dir}
    COMMAND ${cmd}
    MAIN_DEPENDENCY ${src}
    DEPENDS ${A_DEPENDS}
    DEPFILE ${dir}/${A_NAME}.d
    COMMENT "glslang check ${A_NAME}"
    VERBATIM)
  target_sources(${target} PRIVATE ${spv})
endfunction()
