#pragma once
// What the X server shows in the viewer's window (XGetImage), to check in the headless test that
// the presented image reached the display, not only the swapchain image.
#include <cstdint>
#include <vector>

struct GLFWwindow;

namespace viewer {

/// The window's width x height pixels as RGBA8 (alpha 255), row 0 at the top; empty where the
/// window is not an X11 window or the image cannot be read (not a 24/32-bit TrueColor visual).
std::vector<std::uint8_t> readX11Window(GLFWwindow* window, int width, int height);

} // namespace viewer
