#pragma once
// `dispmap render` and the renderer's figures: the table of what each effect costs in GPU time
// against the error it removes (demo and bench), and the "off = not built" comparison.
#include <cstdint>
#include <ostream>
#include <string>

namespace dispmap::figures {

/// Most timed frames of `dispmap render` (each is drawn in full: against typos).
inline constexpr int kMaxRenderFrames = 1000;
/// Most faces per draw call of `dispmap render` (lavapipe is its default device): lavapipe runs
/// one tessellated draw on one thread through a loop whose time grows faster than the patches
/// in it (docs/lavapipe.md). Spot at factor 64 (252 patches, 1.5 million triangles, 320 x 240),
/// one frame on a busy 2-core machine: 1.1 s at 1 face per draw, 1.8 s at 4, 3.4 s at 16 (the
/// default), 25 s at 32, 62 s at 64.
inline constexpr int kMaxFacesPerDraw = 32;
/// Most triangles per frame `dispmap render` draws on a CPU device: lavapipe draws 0.4 to 1.5
/// million a second (Spot above; docs/figures.md's renderer table), so a minute or more.
inline constexpr std::uint64_t kMaxSoftwareTrianglesPerFrame = 50'000'000;

struct RenderArgs {
    std::string scene;        ///< scene file; empty: the embedded default scene
    std::string output;       ///< PNG to write; empty: none
    int frames = 3;           ///< timed frames, 1..kMaxRenderFrames
    int warmup = 1;           ///< untimed frames before them, 0..kMaxRenderFrames (a GPU raises its clocks under load)
    int facesPerDraw = 16;    ///< 1..kMaxFacesPerDraw
    std::string device;       ///< Vulkan device (index or name substring); empty: lavapipe
    bool validation = false;
};
/// Renders one scene headless, writes the PNG, prints GPU time, patches and triangles.
/// Returns the exit status (1 if the validation layer spoke).
int renderCommand(const RenderArgs& args);

struct RenderTableArgs {
    std::string imageDir;     ///< write each row's image here as PNG (empty: none)
    std::string csvPath;      ///< also write the table as CSV (empty: none)
    int frames = 3;           ///< timed frames per row
    int warmup = 1;           ///< untimed frames before them (a GPU raises its clocks under load)
    bool factorSweep = true;  ///< the rows for factors 2..64
    std::string device;
    /// A scene file (JSON, a tessellated surface) instead of the default scene: its mesh,
    /// displacement, camera, lights and resolution; each row sets technique, normals, LOD and
    /// a uniform factor.
    std::string scene;
};
/// The renderer's table on the default scene (or RenderTableArgs::scene), one run: base surface; displaced with
/// approximate, accurate and auto normals; LOD off and on; factors 2..64; the traditional
/// baseline. GPU time (median of `frames`), triangles, and the image error against an
/// accurate-normal, factor-64 reference render. Then the effects table: the frame time of a
/// pipeline with the effects specialised off against one built without them.
void printRenderTable(std::ostream& out, const RenderTableArgs& args);
/// Checks printRenderTable's arguments and reads its scene file (ArgumentError, SceneError):
/// what `dispmap bench` does before its first table.
void checkRenderTableArgs(const RenderTableArgs& args);

} // namespace dispmap::figures
