#pragma once
// `dispmap render` and the renderer's figures: the table of what each effect costs in GPU time
// against the error it removes (demo and bench), and the "off = not built" comparison.
#include <ostream>
#include <string>

namespace dispmap::figures {

struct RenderArgs {
    std::string scene;        ///< scene file; empty: the embedded default scene
    std::string output;       ///< PNG to write; empty: none
    int frames = 3;           ///< timed frames (after one warm-up frame)
    int facesPerDraw = 16;
    std::string device;       ///< Vulkan device (index or name substring); empty: lavapipe
    bool validation = false;
};
/// Renders one scene headless, writes the PNG, prints GPU time, patches and triangles.
/// Returns the exit status (1 if the validation layer spoke).
int renderCommand(const RenderArgs& args);

struct RenderTableArgs {
    std::string imageDir;     ///< write each row's image here as PNG (empty: none)
    std::string csvPath;      ///< also write the table as CSV (empty: none)
    int frames = 3;
    bool factorSweep = true;  ///< the rows for factors 2..64
    std::string device;
};
/// The renderer's table on the default scene, one run: base surface; displaced with
/// approximate, accurate and auto normals; LOD off and on; factors 2..64; the traditional
/// baseline. GPU time (median of `frames`), triangles, and the image error against an
/// accurate-normal, factor-64 reference render. Then the effects table: the frame time of a
/// pipeline with the effects specialised off against one built without them.
void printRenderTable(std::ostream& out, const RenderTableArgs& args);

} // namespace dispmap::figures
