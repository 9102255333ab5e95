// A program outside the project, built against the installed package.
#include <cstdio>
#include <dispmap/kernels/tile.h>
#include <dispmap/surface/tile_builder.h>
#include <dispmap/vulkan/context.h>
#include <string>

int main() {
    const char* quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    dispmap::ControlMesh mesh = dispmap::ControlMesh::fromObjText(quad, "quad");
    dispmap::TileSet tiles = dispmap::buildTiles(mesh, dispmap::uniformTileSizes(mesh, 3),
                                                 dispmap::FunctionSource([](int, double u, double v) { return u * v; }));
    float d = tiles.evaluate(0, 0, glm::vec2(0.5f, 0.5f));
    std::printf("consumer: %d tile(s), D(0.5, 0.5) = %.4f\n", tiles.tileCount(), static_cast<double>(d));
    // The Vulkan backend links without libvulkan (it is opened at run time).
    const std::string name = dispmap::vulkan::resultName(VK_ERROR_DEVICE_LOST);
    std::printf("consumer: %s\n", name.c_str());
    return (tiles.tileCount() == 1 && d > 0.2f && d < 0.3f && name == "VK_ERROR_DEVICE_LOST") ? 0 : 1;
}
