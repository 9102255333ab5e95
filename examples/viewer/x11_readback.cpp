// readX11Window (x11_readback.h): XGetImage of the GLFW window.
#include "x11_readback.h"

#include <GLFW/glfw3.h>
#include <X11/Xlib.h>
#include <X11/Xutil.h>

// GLFW's X11 native access, declared as in <GLFW/glfw3native.h> (which with
// GLFW_EXPOSE_NATIVE_X11 also wants the Xrandr headers, a package more for two declarations).
extern "C" {
Display* glfwGetX11Display(void);
Window glfwGetX11Window(GLFWwindow* window);
}

namespace viewer {

namespace {
int shiftOf(unsigned long mask) {
    int s = 0;
    while (mask && !(mask & 1ul)) {
        mask >>= 1;
        ++s;
    }
    return s;
}
} // namespace

std::vector<std::uint8_t> readX11Window(GLFWwindow* window, int width, int height) {
    Display* display = glfwGetX11Display();
    const Window w = glfwGetX11Window(window);
    if (!display || !w) return {};
    XSync(display, False);
    XImage* image = XGetImage(display, w, 0, 0, static_cast<unsigned>(width), static_cast<unsigned>(height), AllPlanes, ZPixmap);
    if (!image) return {};
    std::vector<std::uint8_t> rgba;
    if (image->bits_per_pixel == 32 && image->red_mask && image->green_mask && image->blue_mask) {
        rgba.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 4);
        const int rs = shiftOf(image->red_mask), gs = shiftOf(image->green_mask), bs = shiftOf(image->blue_mask);
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                const unsigned long p = XGetPixel(image, x, y);
                std::uint8_t* o = &rgba[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 4];
                o[0] = static_cast<std::uint8_t>((p & image->red_mask) >> rs);
                o[1] = static_cast<std::uint8_t>((p & image->green_mask) >> gs);
                o[2] = static_cast<std::uint8_t>((p & image->blue_mask) >> bs);
                o[3] = 255;
            }
    }
    XDestroyImage(image);
    return rgba;
}

} // namespace viewer
