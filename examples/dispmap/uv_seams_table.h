#pragma once
// `dispmap maps --seams`: the traditional baseline on the mesh's own UV layout against its
// seam-free per-face atlas and dispmap: cracks and shading jumps at UV seams, crack pixels in
// renders, pictures (docs/figures.md, "The traditional baseline at UV seams").
#include <ostream>
#include <string>

namespace dispmap::figures {

struct UvSeamsTableArgs {
    std::string dataDir; ///< spot_control_mesh.obj and skimage_brick.png
    bool quick = false;  ///< tiles 2^4 and smaller images (CI)
    std::string device;  ///< Vulkan device (name substring; "": the default)
    std::string images;  ///< folder for the pictures ("": none)
};

void printUvSeamsTable(std::ostream& out, const UvSeamsTableArgs& a);

} // namespace dispmap::figures
