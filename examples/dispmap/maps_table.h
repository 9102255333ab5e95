#pragma once
// `dispmap maps --table`: reading, placing and prefiltering displacement maps, with the cost
// of each choice (docs/figures.md, "Displacement maps").
#include <ostream>
#include <string>

namespace dispmap::figures {

struct MapsTableArgs {
    std::string dataDir; ///< spot_control_mesh.obj and skimage_brick.png
    bool quick = false;  ///< a 512 map for the formats instead of 2048, one error-bound row, one frame a GPU row (CI)
    std::string device;  ///< Vulkan device for the GPU rows (name substring; "": the default)
};

void printMapsTable(std::ostream& out, const MapsTableArgs& a);

} // namespace dispmap::figures
