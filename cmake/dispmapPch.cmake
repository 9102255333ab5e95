# dispmap_precompile(target [CATCH] [VULKAN] [CLI]): precompiled headers for the project's own
# test and tool targets (never for the library, which stays header-only and is not touched).
# The set is the standard and third-party headers most of their translation units parse; the
# project's own headers stay out, so an edited header rebuilds only the files that include it.
# The build-time comparison, and the command that measures it, is in docs/figures.md ("Build time").
function(dispmap_precompile target)
  cmake_parse_arguments(PARSE_ARGV 1 A "CATCH;VULKAN;CLI" "" "")
  set(headers
    <algorithm> <array> <cmath> <cstdint> <cstring> <filesystem> <functional> <limits> <map>
    <memory> <random> <set> <sstream> <string> <thread> <unordered_map> <vector>
    <glm/glm.hpp>
    <opensubdiv/far/patchMap.h> <opensubdiv/far/patchTable.h> <opensubdiv/far/patchTableFactory.h>
    <opensubdiv/far/primvarRefiner.h> <opensubdiv/far/ptexIndices.h> <opensubdiv/far/topologyRefinerFactory.h>
    <nlohmann/json.hpp> <tiny_obj_loader.h>)
  if(A_CATCH)
    list(APPEND headers <catch2/catch.hpp>)
  endif()
  if(A_VULKAN)
    list(APPEND headers <vulkan/vulkan.h>)
  endif()
  if(A_CLI)
    list(APPEND headers <CLI/CLI.hpp> <benchmark/benchmark.h>)
  endif()
  target_precompile_headers(${target} PRIVATE ${headers})
endfunction()
