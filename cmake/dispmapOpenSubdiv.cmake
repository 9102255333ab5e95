# Locates OpenSubdiv's CPU library as the imported target dispmap_deps::osdCPU.
# Debian 12's OpenSubdivTargets.cmake names static libraries that libosd-dev does not ship,
# so find_package(OpenSubdiv CONFIG) fails there; we look the library up directly.
if(NOT TARGET dispmap_deps::osdCPU)
  find_path(DISPMAP_OSD_INCLUDE_DIR opensubdiv/far/topologyRefiner.h)
  find_library(DISPMAP_OSD_CPU_LIBRARY NAMES osdCPU)
  if(DISPMAP_OSD_INCLUDE_DIR AND DISPMAP_OSD_CPU_LIBRARY)
    add_library(dispmap_deps::osdCPU UNKNOWN IMPORTED)
    set_target_properties(dispmap_deps::osdCPU PROPERTIES
      IMPORTED_LOCATION "${DISPMAP_OSD_CPU_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${DISPMAP_OSD_INCLUDE_DIR}")
  endif()
endif()
