// `dispmap maps --table`: what reading real displacement maps costs and how accurate it is
// (docs/figures.md, "Displacement maps"): file formats, prefilters, tile sizes from the texel
// density, and linear against smooth UVs.
#include "maps_table.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include "text_format.h"
#include "dispmap/io/image_files.h"
#include "dispmap/io/png.h"
#include "dispmap/io/tile_file.h"
#include "dispmap/surface/map_source.h"
#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/mesh.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/draw.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/vulkan/context.h"
#include "dispmap/vulkan/renderer.h"

namespace dispmap::figures {

namespace {

double secondsSince(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}


/// Max and RMS of D(tiles) - ref(face, u, v) over n x n points of every tile.
struct Errors {
    double max = 0, rms = 0;
};
template <typename F> Errors tileErrors(const TileSet& ts, int n, F ref) {
    Errors e;
    double sum = 0.0;
    std::size_t count = 0;
    for (int t = 0; t < ts.tileCount(); ++t)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const glm::dvec2 uv((i + 0.5) / n, (j + 0.5) / n);
                const double d = ts.evaluate<double>(t, 0, uv) - ref(t, uv.x, uv.y);
                e.max = std::max(e.max, std::abs(d));
                sum += d * d;
                ++count;
            }
    e.rms = std::sqrt(sum / static_cast<double>(count));
    return e;
}

// Periodic in s and t with period 1: Spot's UVs wrap.
double wavy(double s, double t) {
    constexpr double tau = 6.283185307179586;
    return 0.5 + 0.3 * std::sin(tau * s + 1.0) * std::cos(2.0 * tau * t) + 0.1 * std::sin(3.0 * tau * (s + t));
}

} // namespace

TileSet spotBrickTiles(const ControlMesh& spot, std::shared_ptr<const UvMap> uvs, const HeightMaps& brick, int k, int threads) {
    const std::vector<int> sizes = uniformTileSizes(spot, k);
    MapSourceOptions o;
    o.wrap = true;
    o.filter = MapFilter::Box;
    o.scale = 0.03;
    o.midLevel = 0.5;
    BuildOptions bo;
    bo.threads = threads;
    return buildTiles(spot, sizes, mapSource(std::move(uvs), brick, sizes, o), bo);
}

void printMapsTable(std::ostream& out, const MapsTableArgs& a) {
    const ControlMesh spot = ControlMesh::fromObjFile(a.dataDir + "/spot_control_mesh.obj");
    const HeightImage brickImage = readHeightImage(a.dataDir + "/skimage_brick.png");
    HeightMaps brick;
    brick.images[0] = std::make_shared<const HeightImage>(brickImage);
    const auto linear = std::make_shared<const UvMap>(spot, UvInterpolation::Linear);
    const auto smooth = std::make_shared<const UvMap>(spot, UvInterpolation::Smooth);
    // The brick map at full resolution where Spot's linear UVs put (face, u, v).
    const auto fullRes = [&](int t, double u, double v) {
        const glm::dvec2 p = (*linear)(t, u, v);
        return sampleHeightBilinear(brickImage, p.x, p.y, true);
    };

    // --- 1. Formats: an analytic height field written in each, read back, placed on Spot.
    {
        const int size = a.quick ? 512 : 2048;
        HeightImage img;
        img.width = img.height = size;
        for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x) img.values.push_back(static_cast<float>(wavy((x + 0.5) / size, 1.0 - (y + 0.5) / size)));
        const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("dispmap-maps-" + std::to_string(::getpid()));
        std::filesystem::create_directories(dir);
        struct Format {
            const char* name;
            std::string file;
            double quantum; // the format's rounding of a height in [0, 1]
        };
        const std::vector<Format> formats = {
            {"PNG 16-bit", (dir / "h16.png").string(), 0.5 / 65535},  {"TIFF 8-bit", (dir / "h8.tif").string(), 0.5 / 255},
            {"TIFF 16-bit", (dir / "h16.tif").string(), 0.5 / 65535}, {"TIFF 32-bit float", (dir / "hf.tif").string(), 0},
            {"EXR half", (dir / "hh.exr").string(), 2.5e-4},        {"EXR float", (dir / "hf.exr").string(), 0},
        };
        writeHeightPng16(formats[0].file, img);
        writeHeightTiff(formats[1].file, img, 8, false);
        writeHeightTiff(formats[2].file, img, 16, false);
        writeHeightTiff(formats[3].file, img, 32, true);
        writeHeightExr(formats[4].file, img, true);
        writeHeightExr(formats[5].file, img, false);
        const std::vector<int> k = uniformTileSizes(spot, 5);
        const auto truth = [&](int t, double u, double v) {
            glm::dvec2 p = (*linear)(t, u, v);
            p -= glm::floor(p); // Spot's UVs reach past [0, 1]: the map wraps
            return wavy(p.x, p.y);
        };
        out << "Formats: a " << size << " x " << size << " analytic height field written in each format, read back and "
            << "placed on Spot (" << spot.ptexFaceCount() << " Ptex faces, 32 x 32 tiles (sub-faces 16 x 16), point samples, wrap). Error of D against the "
            << "function at 8 x 8 points per tile (|D| <= 1; its maximum is the Doo-Sabin corner constraint at extraordinary "
            << "vertices, D_u = D_v = 0 there, whatever the format):\n\n";
        out << "| format | file bytes | read s | read-back max abs h error | format's rounding | place + fit s | max error of D | rms error of D |\n";
        out << "|---|---:|---:|---:|---:|---:|---:|---:|\n";
        for (const Format& f : formats) {
            auto t0 = std::chrono::steady_clock::now();
            HeightMaps maps;
            maps.images[0] = std::make_shared<const HeightImage>(readHeightImage(f.file));
            const double read = secondsSince(t0);
            double readBack = 0.0;
            for (std::size_t i = 0; i < img.values.size(); ++i)
                readBack = std::max(readBack, std::abs(static_cast<double>(maps.images[0]->values[i]) - static_cast<double>(img.values[i])));
            t0 = std::chrono::steady_clock::now();
            MapSourceOptions o;
            o.wrap = true;
            const TileSet ts = buildTiles(spot, k, mapSource(linear, maps, k, o));
            const double fit = secondsSince(t0);
            const Errors e = tileErrors(ts, 8, truth);
            out << "| " << f.name << " | " << std::filesystem::file_size(f.file) << " | " << fixed(read, 3) << " | " << sci(readBack)
                << " | " << (f.quantum > 0 ? sci(f.quantum) : "float") << " | " << fixed(fit, 2) << " | " << sci(e.max) << " | "
                << sci(e.rms) << " |\n";
        }
        std::filesystem::remove_all(dir);
        out << "\n";
    }

    // --- 2. Prefilters: the brick map on Spot at tile sizes below its texel density.
    {
        out << "Prefilters: the 512 x 512 brick map on Spot (linear UVs, wrap). Error of D against the full-resolution map at 16 x 16 "
            << "points per tile; a sample of a 2^k tile spans about 20 / 2^k texels of this map (5-50 / 2^k by face):\n\n";
        out << "| k | filter | build s | max error | rms error |\n|---:|---|---:|---:|---:|\n";
        for (int kk : {2, 3, 4}) {
            const std::vector<int> k = uniformTileSizes(spot, kk);
            for (MapFilter f : {MapFilter::Point, MapFilter::Box, MapFilter::Tent}) {
                MapSourceOptions o;
                o.wrap = true;
                o.filter = f;
                const auto t0 = std::chrono::steady_clock::now();
                const TileSet ts = buildTiles(spot, k, mapSource(linear, brick, k, o));
                const double s = secondsSince(t0);
                const Errors e = tileErrors(ts, 16, fullRes);
                out << "| " << kk << " | " << toString(f) << " | " << fixed(s, 2) << " | " << fixed(e.max, 4) << " | " << fixed(e.rms, 4) << " |\n";
            }
        }
        out << "\n";
    }

    // --- 3. Tile sizes from the texel density against uniform sizes.
    {
        out << "Tile sizes: the brick map on Spot, box filter. Uniform 2^k against per-face sizes from the map's texel density "
            << "(at most 2^k) and from a fit-error bound (errorTileSizes: the smallest k whose box-filtered samples reproduce the "
            << "2^6 samples within the tolerance, heights in [0, 1]); build s includes choosing the sizes; error against the "
            << "full-resolution map at 16 x 16 points per tile. The last two rows: the map with its left half flat (detail on "
            << "part of the model):\n\n";
        out << "| sizes | k (max) | texels | tile file bytes | build s | max error | rms error |\n|---|---:|---:|---:|---:|---:|---:|\n";
        MapSourceOptions o;
        o.wrap = true;
        o.filter = MapFilter::Box;
        // The bricks on the right half of the map only (s >= 0.5), the left half flat at 0.5: detail
        // on part of a model, as sculpts have it.
        HeightImage halfImage = brickImage;
        for (int y = 0; y < halfImage.height; ++y)
            for (int x = 0; x < halfImage.width / 2; ++x) halfImage.values[static_cast<std::size_t>(y * halfImage.width + x)] = 0.5f;
        HeightMaps half;
        half.images[0] = std::make_shared<const HeightImage>(halfImage);
        const auto halfRes = [&](int t, double u, double v) {
            const glm::dvec2 p = (*linear)(t, u, v);
            return sampleHeightBilinear(halfImage, p.x, p.y, true);
        };
        const auto row = [&](const std::string& name, int kk, auto sizes, bool halfFlat = false) {
            const auto t0 = std::chrono::steady_clock::now();
            const std::vector<int> k = sizes();
            const TileSet ts = buildTiles(spot, k, mapSource(linear, halfFlat ? half : brick, k, o));
            const double s = secondsSince(t0);
            std::uint64_t count = 0;
            for (int t = 0; t < ts.tileCount(); ++t) count += static_cast<std::uint64_t>(1) << (2 * k[static_cast<std::size_t>(t)]);
            const Errors e = halfFlat ? tileErrors(ts, 16, halfRes) : tileErrors(ts, 16, fullRes);
            out << "| " << name << " | " << kk << " | " << count << " | " << tileFileBytes(ts) << " | " << fixed(s, 2) << " | "
                << fixed(e.max, 4) << " | " << fixed(e.rms, 4) << " |\n";
        };
        for (int kk : {4, 5, 6}) {
            row("uniform", kk, [&] { return uniformTileSizes(spot, kk); });
            row("texel density", kk, [&] { return texelTileSizes(spot, *linear, brick, kMinTileLog2, kk); });
        }
        // --quick (CI, also under the sanitizers): one error-bound row, no half-flat rows.
        for (double tolerance : a.quick ? std::vector<double>{0.05} : std::vector<double>{0.2, 0.1, 0.05, 0.025})
            row("fit error <= " + fixed(tolerance, 3), 6, [&] { return errorTileSizes(spot, linear, brick, kMinTileLog2, 6, tolerance, o); });
        if (!a.quick) {
            row("uniform, half-flat map", 6, [&] { return uniformTileSizes(spot, 6); }, true);
            row("fit error <= 0.025, half-flat map", 6, [&] { return errorTileSizes(spot, linear, half, kMinTileLog2, 6, 0.025, o); }, true);
        }
        out << "\n";
    }

    // --- 4. Smooth against linear UVs: a map painted on the smooth UV layout.
    {
        double layouts = 0.0;
        for (int t = 0; t < spot.ptexFaceCount(); ++t)
            for (int j = 0; j <= 4; ++j)
                for (int i = 0; i <= 4; ++i)
                    layouts = std::max(layouts, glm::length((*smooth)(t, i / 4.0, j / 4.0) - (*linear)(t, i / 4.0, j / 4.0)));
        const auto truth = [&](int t, double u, double v) {
            glm::dvec2 p = (*smooth)(t, u, v);
            p -= glm::floor(p);
            return sampleHeightBilinear(brickImage, p.x, p.y, true);
        };
        out << "UV interpolation: Spot's smooth (face-varying, OpenSubdiv's FVAR_LINEAR_NONE) and linear UV layouts differ by up to "
            << fixed(layouts * 512, 1) << " texels of a 512 map. The brick map, painted on the smooth layout, placed with each rule "
            << "(k = 5, box filter); error against the map on the smooth layout:\n\n";
        out << "| UVs | place + fit s | max error | rms error |\n|---|---:|---:|---:|\n";
        const std::vector<int> k = uniformTileSizes(spot, 5);
        for (const auto& [name, uvs] : {std::pair{"linear", linear}, std::pair{"smooth", smooth}}) {
            MapSourceOptions o;
            o.wrap = true;
            o.filter = MapFilter::Box;
            const auto t0 = std::chrono::steady_clock::now();
            const TileSet ts = buildTiles(spot, k, mapSource(uvs, brick, k, o));
            const double s = secondsSince(t0);
            const Errors e = tileErrors(ts, 16, truth);
            out << "| " << name << " | " << fixed(s, 2) << " | " << fixed(e.max, 4) << " | " << fixed(e.rms, 4) << " |\n";
        }
        out << "\n";
    }

    // --- 5. The tiles' texels on the GPU: float or half, storage buffer or sampled image.
    {
        vulkan::DeviceOptions dopt;
        dopt.device = a.device;
        vulkan::Context ctx(dopt);
        const TileSet tiles = spotBrickTiles(spot, linear, brick, 5);
        const BaseSurface base(spot);
        const DisplacedSurface surface(base, tiles);
        const PackedTiles full = tiles.pack();
        PackedTiles half = full;
        half.useHalf();
        // D and its derivatives from half texels against float texels, over 8 x 8 points a tile
        double dMax = 0.0, dErr = 0.0, gradErr = 0.0, gradMax = 0.0;
        for (int r = 0; r < static_cast<int>(full.records.size()); ++r)
            for (int j = 0; j < 8; ++j)
                for (int i = 0; i < 8; ++i) {
                    const glm::dvec2 uv((i + 0.5) / 8, (j + 0.5) / 8);
                    const glm::dvec3 f = full.sampleD1<double>(r, uv, 64.0), h = half.sampleD1<double>(r, uv, 64.0);
                    dMax = std::max(dMax, std::abs(f.x));
                    dErr = std::max(dErr, std::abs(h.x - f.x));
                    gradMax = std::max(gradMax, glm::length(glm::dvec2(f.y, f.z)));
                    gradErr = std::max(gradErr, glm::length(glm::dvec2(h.y - f.y, h.z - f.z)));
                }
        SurfaceDraw draw;
        draw.width = a.quick ? 320 : 640;
        draw.height = a.quick ? 240 : 480;
        draw.camera.eye = glm::dvec3(2.3, 0.8, -1.2);
        draw.camera.target = glm::dvec3(0, 0.25, 0);
        draw.camera.fovYDeg = 35;
        draw.effects.tessValue = 16;
        const int frames = a.quick ? 1 : 5;
        out << "Texels on the GPU (" << ctx.deviceName() << "): the brick map on Spot, 2^5 tiles, " << full.width << " x " << full.height
            << " packed texels, rendered " << draw.width << " x " << draw.height << " at factor 16 (median of " << frames
            << " frames). Half texels change D by " << sci(dErr / dMax) << " of max |D| and its gradient by " << sci(gradErr / gradMax)
            << " of the largest; the GPU reads every path exactly (tests: bit for bit the CPU's texels):\n\n";
        out << "| texels | path | texel bytes | max error of D (of max abs D) | GPU ms |\n|---|---|---:|---:|---:|\n";
        for (const TexelFormat format : {TexelFormat::Float, TexelFormat::Half})
            for (const TexelPath path : {TexelPath::Buffer, TexelPath::Image}) {
                draw.effects.texelFormat = format;
                draw.effects.texelPath = path;
                vulkan::SurfaceRenderer r(ctx, draw, surface);
                const double ms = r.render(frames, 1).stats.gpuMs;
                const std::size_t bytes = full.texels.size() * (format == TexelFormat::Half ? 2 : 4);
                out << "| " << toString(format) << " | " << toString(path) << " | " << bytes << " | "
                    << (format == TexelFormat::Half ? sci(dErr / dMax) : std::string("0")) << " | " << fixed(ms, 1) << " |\n";
            }
        out << "\n";
    }
}

} // namespace dispmap::figures
