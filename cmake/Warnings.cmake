# Strict warnings as errors for every target this project builds (consumers of the
# installed package do not inherit them). -ffp-contract=off keeps the CPU from fusing
# multiply-adds, so that C++ and GLSL evaluate the same expressions (docs/lavapipe.md).
add_library(dispmap_warnings INTERFACE)
target_compile_options(dispmap_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Werror
  -Wconversion -Wsign-conversion -Wdouble-promotion -Wshadow -Wold-style-cast
  -Wcast-align -Wnon-virtual-dtor -Woverloaded-virtual -Wnull-dereference
  -Wimplicit-fallthrough -Wmissing-declarations
  -ffp-contract=off)
