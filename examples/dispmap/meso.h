#pragma once
// Per-pixel mesostructure figures: the scenes, the camera that turns pixels into
// voxel-space rays, the accuracy-vs-time table (Mehra & Kumar Tables 1-3 measured here) and
// the iteration pictures (their Figure 7), and `dispmap meso`.
#include <functional>
#include <ostream>
#include <map>
#include <string>
#include <vector>

#include "dispmap/io/png.h"
#include "dispmap/meso/march.h"

namespace dispmap::figures {

/// A pinhole camera in voxel space looking at the slab's top plane z = L.
struct MesoCamera {
    glm::dvec3 eye{0}, target{0};
    double fovDeg = 50;
    int width = 160, height = 120;
    /// The ray of pixel (x, y) (row 0 at the top) started where it enters the slab's top plane;
    /// false for a pixel whose ray never comes down to it (the sky).
    bool ray(int x, int y, int layers, glm::dvec3& o, glm::dvec3& d) const;
};

/// A scene: a height field and the camera the table looks at it with.
struct MesoScene {
    std::string name;
    MesoHeightField field;
    MesoCamera camera;
};
/// "bricks" (tests/data/skimage_brick.png, 128 x 128 x 16) and "grating" (walls one texel wide
/// and one-texel beads, 64 x 64 x 16: the thin features of Donnelly's Fig. 8-6).
std::vector<MesoScene> mesoScenes(const std::string& dataDir);

/// The maps of `field` for each cone set named (parseConeSet), keyed by the name: the distance
/// map and the quadrics, which do not depend on the cones, are built once and copied into
/// every set. `threads` as MesoMapOptions::threads.
std::map<std::string, MesoMaps> buildConeSetMaps(const MesoHeightField& field, const std::vector<std::string>& coneSets, int threads = 0);

/// The seven cone sets of the table: isotropic, 2x1, 4x1, 8x1, 2x2, 4x2, 8x2.
const std::vector<std::string>& tableConeSets();

/// One row of the table: a technique with a label.
struct MesoRow {
    std::string label;
    MesoTechnique technique;
    std::string map; ///< which map it reads: "distance", "ddm:<cones>", "heights"
};
std::vector<MesoRow> mesoRows();

struct MesoTableArgs {
    std::string dataDir;      ///< where skimage_brick.png is
    std::string csv;          ///< also write the table as CSV
    std::string images;       ///< folder for the iteration pictures (PNG), empty: none
    double minSeconds = 0.15; ///< CPU timing: repeat a frame for at least this long
    /// The GPU column: each height-field row rendered by the fragment-shader marcher (the same
    /// camera and pixels, Vulkan device `device`, lavapipe by default), median frame time.
    bool gpu = true;
    std::string device;
    int gpuFrames = 5;
    int gpuWarmup = 1; ///< untimed frames before them (a GPU raises its clocks under load)
};
/// Prints, per scene, iterations (mean, p99), hit error against the exact reference (mean,
/// p99, texels; misses and false hits as a share), memory read by the method (uncompressed and
/// compressed), CPU time per frame (float, one thread) and the GPU column; then the goals
/// and the compression table.
void printMesoTable(std::ostream& out, const MesoTableArgs& args);

/// The curved-base table (`dispmap meso --curved`): the locally planar march against the exact
/// shell of a cylinder, per slab depth / radius and incidence (texel error of the hits, false
/// hits at silhouettes), then the renderer's time on the Spot scene beside the plane (when
/// args.gpu and a device opens). Reads args.dataDir's scenes/meso_spot_grating.json.
void printMesoCurvedTable(std::ostream& out, const MesoTableArgs& args);

/// Colour of an iteration count as the paper's Figure 7 codes it: blue 0-10, green 10-34,
/// red 35-59, yellow 60-100 (white above).
void iterationColour(int iterations, unsigned char rgb[3]);

} // namespace dispmap::figures
