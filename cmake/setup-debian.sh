#!/usr/bin/env bash
# Installs the Debian 12 packages dispmap builds and tests with.
# Idempotent and quiet: when every package is present it prints nothing and touches nothing.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libglm-dev            # vector maths; the only dependency of the header-only kernels
  libosd-dev            # OpenSubdiv 3.5: Far topology, PtexIndices, Bfr limit evaluation
  libtinyobjloader-dev  # OBJ reading, including OpenSubdiv's crease/corner/hole tag lines
  libpng-dev            # 16-bit greyscale height images
  libopenexr-dev        # EXR height images (half/float) from sculpting tools; brings Imath
  libtiff-dev           # TIFF height images (8/16/32-bit integer and float) from sculpting tools
  libcli11-dev          # command-line parsing of the dispmap program
  nlohmann-json3-dev    # JSON output of `dispmap eval` (and scene files)
  libembree-dev         # bake: ray casting and closest points on dense meshes (Embree 3)
  libtbb-dev            # bake: all cores for the fitting, extraction and error measurement
  libmeshoptimizer-dev  # bake: simplification of a dense mesh to a base mesh (the DSS route)
  libassimp-dev         # bake: PLY (ASCII, binary) and OFF dense meshes
  libtinygltf-dev       # dispmap tessellate: glTF 2.0 export (tinygltf)
  libnanoflann-dev      # bake: nearest dense vertex in position+normal space (k-d tree)
  catch2                # unit tests (Catch2 v2) under CTest
  libbenchmark-dev      # Google Benchmark for the figures
  glslang-tools         # glslangValidator: every generated GLSL include and shader compiled to SPIR-V
  libvulkan-dev         # Vulkan headers and loader (the backend loads libvulkan.so.1 at run time)
  mesa-vulkan-drivers   # lavapipe, the default (CPU) Vulkan device of the tests
  vulkan-validationlayers  # VK_LAYER_KHRONOS_validation: the Vulkan tests fail on any message
  libglfw3-dev          # examples/viewer: the interactive viewer's window, input and Vulkan surface (GLFW 3.3)
  libx11-dev            # examples/viewer: XGetImage, the viewer's test reads back what the X server shows
  xvfb                  # examples/viewer tests: a virtual X server (xvfb-run) the viewer presents to headless
  xauth                 # xvfb-run needs xauth to create the X authority file for its server
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "setup: installing ${missing[*]}" >&2
sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
