// The mesostructure table and pictures (examples/meso.h).
#include "meso.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <map>
#include <memory>
#include <sstream>

#include "dispmap/io/png.h"
#include "dispmap/scene/meso.h"
#include "dispmap/meso/solid.h"
#include "dispmap/vulkan/meso_renderer.h"
#include "figures.h"
#include "text_format.h"

namespace dispmap::figures {

bool MesoCamera::ray(int x, int y, int layers, glm::dvec3& o, glm::dvec3& d) const {
    const glm::dvec3 f = glm::normalize(target - eye), r = glm::normalize(glm::cross(f, glm::dvec3(0, 0, 1)));
    const glm::dvec3 u = glm::cross(r, f);
    const double th = std::tan(0.5 * fovDeg * 3.14159265358979323846 / 180.0), aspect = double(width) / height;
    const double sx = (2.0 * (x + 0.5) / width - 1.0) * th * aspect, sy = (1.0 - 2.0 * (y + 0.5) / height) * th;
    d = glm::normalize(f + sx * r + sy * u);
    if (eye.z <= layers) {
        o = eye;
        return true;
    }
    if (!(d.z < -1e-6)) return false;
    o = eye + d * ((layers - eye.z) / d.z);
    o.z = layers; // exactly on the plane
    return true;
}

namespace {
MesoHeightField downsample(const HeightImage& img, int size, int layers, double depth) {
    return mesoHeightFieldFromImage(downsampleHeightImage(img, size), layers, depth);
}

MesoCamera tableCamera(int size, int layers) {
    MesoCamera c;
    c.eye = glm::dvec3(0.5 * size, -0.15 * size, layers + 0.35 * size);
    c.target = glm::dvec3(0.5 * size, 0.55 * size, 0.0);
    c.fovDeg = 55;
    return c;
}

struct Stats {
    double meanIt = 0, p99It = 0, meanErr = 0, p99Err = 0, wrong = 0, ms = 0, gpu = -1;
    std::vector<int> iterations; // per pixel, -1 = sky
};

double percentile(std::vector<double> v, double p) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

struct Pixel {
    glm::dvec3 o, d;
    MesoHit ref;
    bool sky;
};

// Pixel rays of the camera with their exact reference hits.
std::vector<Pixel> pixels(const MesoCamera& cam, int layers, const std::function<MesoHit(const glm::dvec3&, const glm::dvec3&)>& reference) {
    std::vector<Pixel> px(static_cast<std::size_t>(cam.width * cam.height));
    for (int y = 0; y < cam.height; ++y)
        for (int x = 0; x < cam.width; ++x) {
            Pixel& p = px[static_cast<std::size_t>(y * cam.width + x)];
            p.sky = !cam.ray(x, y, layers, p.o, p.d);
            if (!p.sky) p.ref = reference(p.o, p.d);
        }
    return px;
}

// One row: every pixel through `march`, timed over whole frames (one thread, repeated for at
// least minSeconds), iterations and errors against the reference.
Stats measure(const std::vector<Pixel>& px, const std::function<MesoHit(const glm::dvec3&, const glm::dvec3&)>& march, double minSeconds) {
    Stats st;
    st.iterations.assign(px.size(), -1);
    std::vector<double> its, errs;
    std::size_t wrong = 0, rays = 0;
    std::vector<MesoHit> hits(px.size());
    int frames = 0;
    const auto c0 = std::chrono::steady_clock::now();
    double elapsed = 0;
    do {
        for (std::size_t i = 0; i < px.size(); ++i)
            if (!px[i].sky) hits[i] = march(px[i].o, px[i].d);
        ++frames;
        elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
    } while (elapsed < minSeconds);
    st.ms = 1e3 * elapsed / frames;
    for (std::size_t i = 0; i < px.size(); ++i) {
        if (px[i].sky) continue;
        ++rays;
        const MesoHit& h = hits[i];
        st.iterations[i] = h.iterations;
        its.push_back(h.iterations);
        if (h.hit != px[i].ref.hit) {
            ++wrong;
            continue;
        }
        if (!h.hit) continue;
        const double e = glm::length(h.point(px[i].o, px[i].d) - px[i].ref.point(px[i].o, px[i].d));
        errs.push_back(e);
        if (e > 1.0) ++wrong; // off by more than a texel: a different feature
    }
    for (double v : its) st.meanIt += v / static_cast<double>(its.size());
    for (double v : errs) st.meanErr += v / static_cast<double>(errs.size());
    st.p99It = percentile(its, 0.99);
    st.p99Err = percentile(errs, 0.99);
    st.wrong = static_cast<double>(wrong) / static_cast<double>(std::max<std::size_t>(rays, 1));
    return st;
}

// The fragment shader's frame time for the table's camera: voxel space is world space scaled
// by tileSize / W (cubic voxels) with the slab's top at z = 0.
// With an albedo and a normal map when given (the shading row).
double gpuFrameMs(vulkan::Context& ctx, const MesoCamera& camera, const MesoMaps& m, const MesoTechnique& t, int frames, int warmup,
                  std::shared_ptr<const MesoAlbedo> albedo = nullptr, std::shared_ptr<const MesoAlbedo> normalMap = nullptr) {
    const MesoHeightField& f = m.field; // a solid's: its sizes
    vulkan::MesoRenderOptions o;
    o.width = camera.width;
    o.height = camera.height;
    o.tileSize = 1.0;
    const double s = o.tileSize / f.width;
    o.depth = f.layers * s;
    const auto world = [&](glm::dvec3 v) { return glm::dvec3(v.x * s, v.y * s, (v.z - f.layers) * s); };
    o.camera.eye = world(camera.eye);
    o.camera.target = world(camera.target);
    o.camera.fovYDeg = camera.fovDeg;
    o.planeHalfSize = 12.0; // the far rows reach ~5 tiles away
    o.quads = 8;
    o.technique = t;
    o.frames = frames;
    o.warmup = warmup;
    o.albedo = std::move(albedo);
    o.normalMap = std::move(normalMap);
    return vulkan::renderMeso(ctx, m, o).gpuMs;
}

// One row of the compression table (Table 3).
void compressionRow(std::ostream& out, const std::string& scene, const std::string& cones, std::size_t dense, const CompressedDdm& c) {
    out << std::fixed << "  " << std::left << std::setw(10) << scene << std::setw(11) << cones << std::right << std::setw(9)
        << dense / 1024 << " KiB" << std::setw(8) << c.grid.size() * 4 / 1024 << " KiB" << std::setw(8) << c.atlas.size() * 4 / 1024
        << " KiB" << std::setw(8) << c.planes.size() * 4 / 1024 << " KiB" << std::setw(8) << std::setprecision(1) << c.ratio() << "x"
        << std::setw(8) << 100.0 * static_cast<double>(c.atlasBlocks()) / static_cast<double>(c.grid.size()) << "%" << std::setw(8)
        << 100.0 * static_cast<double>(c.planeBlocks()) / static_cast<double>(c.grid.size()) << "%\n";
}

void printHeader(std::ostream& out) {
    out << std::left << std::setw(48) << "method" << std::right << std::setw(8) << "it mean" << std::setw(7) << "it p99" << std::setw(10)
        << "err mean" << std::setw(9) << "err p99" << std::setw(8) << "wrong" << std::setw(11) << "memory" << std::setw(11)
        << "compressed" << std::setw(9) << "CPU ms" << std::setw(9) << "GPU ms" << "\n";
}

void printRow(std::ostream& out, CsvOut& csv, const std::string& scene, const std::string& label, const Stats& st, std::size_t bytes,
              std::size_t compressed) {
    out << std::left << std::setw(48) << label << std::right << std::fixed << std::setprecision(1) << std::setw(8) << st.meanIt
        << std::setw(7) << std::setprecision(0) << st.p99It << std::setprecision(3) << std::setw(10) << st.meanErr << std::setw(9)
        << st.p99Err << std::setprecision(1) << std::setw(7) << 100 * st.wrong << "%" << std::setw(8) << bytes / 1024 << " KiB"
        << std::setw(7) << compressed / 1024 << " KiB" << std::setprecision(2) << std::setw(9) << st.ms;
    if (st.gpu >= 0) out << std::setw(9) << st.gpu;
    else out << std::setw(9) << "-";
    out << "\n";
    csv << scene << "," << label << "," << st.meanIt << "," << st.p99It << "," << st.meanErr << "," << st.p99Err << "," << st.wrong << ","
        << bytes << "," << compressed << "," << st.ms << "," << st.gpu << "\n";
}

void writePicture(const std::string& path, const MesoCamera& cam, const std::vector<std::pair<std::string, Stats>>& pictures) {
    // The methods side by side, 4 per row (Figure 7's colours).
    const int cols = 4, rowsN = static_cast<int>((pictures.size() + cols - 1) / cols), gap = 4;
    const int W = cols * cam.width + (cols - 1) * gap, H = rowsN * cam.height + (rowsN - 1) * gap;
    std::vector<std::uint8_t> rgba(static_cast<std::size_t>(W * H) * 4, 255);
    for (std::size_t k = 0; k < pictures.size(); ++k) {
        const int ox = static_cast<int>(k % cols) * (cam.width + gap), oy = static_cast<int>(k / cols) * (cam.height + gap);
        for (int y = 0; y < cam.height; ++y)
            for (int x = 0; x < cam.width; ++x) {
                const int n = pictures[k].second.iterations[static_cast<std::size_t>(y * cam.width + x)];
                unsigned char c[3] = {20, 20, 20};
                if (n >= 0) iterationColour(n, c);
                std::uint8_t* p = &rgba[(static_cast<std::size_t>(oy + y) * static_cast<std::size_t>(W) + static_cast<std::size_t>(ox + x)) * 4];
                p[0] = c[0];
                p[1] = c[1];
                p[2] = c[2];
            }
    }
    writeRgbaPng(path, W, H, rgba.data());
}

std::ostream& pictureNote(std::ostream& out, const std::string& path, const std::vector<std::pair<std::string, Stats>>& pictures) {
    out << "(iteration picture: " << path << ", left to right, top to bottom:";
    for (const auto& p : pictures) out << " " << p.first << ";";
    return out << " blue < 10, green < 35, red < 60, yellow <= 100, white > 100, grey sky)\n";
}

} // namespace

std::map<std::string, MesoMaps> buildConeSetMaps(const MesoHeightField& field, const std::vector<std::string>& coneSets, int threads) {
    std::map<std::string, MesoMaps> maps;
    const MesoMaps* shared = nullptr;
    for (const std::string& cones : coneSets) {
        MesoMapOptions o;
        o.cones = parseConeSet(cones);
        o.threads = threads;
        o.distance = o.quadrics = shared == nullptr;
        MesoMaps m = buildMesoMaps(field, o);
        if (shared) {
            m.distance = shared->distance;
            m.quadrics = shared->quadrics;
        }
        shared = &maps.emplace(cones, std::move(m)).first->second;
    }
    return maps;
}

const std::vector<std::string>& tableConeSets() {
    static const std::vector<std::string> sets{"isotropic", "2x1", "4x1", "8x1", "2x2", "4x2", "8x2"};
    return sets;
}

std::vector<MesoScene> mesoScenes(const std::string& dataDir) {
    std::vector<MesoScene> s;
    {
        MesoScene b;
        b.name = "bricks";
        const int size = 128, layers = 16;
        b.field = downsample(readHeightPng(dataDir + "/skimage_brick.png"), size, layers, 0.9 * layers);
        b.camera = tableCamera(size, layers);
        s.push_back(std::move(b));
    }
    {
        MesoScene g;
        g.name = "grating";
        const int size = 64, layers = 16;
        g.field = mesoFunctionField("grating", size, layers);
        g.camera = tableCamera(size, layers);
        s.push_back(std::move(g));
    }
    return s;
}

std::vector<MesoRow> mesoRows() {
    std::vector<MesoRow> rows;
    auto dm = [&](int n, double eps) {
        MesoTechnique t;
        t.method = MesoMethod::DistanceMap;
        t.iterations = n;
        t.eps = eps;
        rows.push_back({eps < 0 ? "distance map, " + std::to_string(n) + " steps" : "distance map, eps 0.02", t, "distance"});
    };
    dm(8, -1);
    dm(16, -1);
    dm(32, -1);
    dm(64, -1);
    dm(256, 0.02);
    auto ddm = [&](const std::string& cones, bool quadrics, int exitRule, const std::string& extra) {
        MesoTechnique t;
        t.method = MesoMethod::Ddm;
        t.iterations = 1024;
        t.quadrics = quadrics;
        t.exitRule = exitRule;
        const std::string name = cones == "isotropic" ? "conservative isotropic" : "DDM " + cones;
        rows.push_back({name + (quadrics ? " + quadric" : "") + extra, t, "ddm:" + cones});
    };
    ddm("isotropic", false, 1, "");
    ddm("2x1", false, 1, "");
    ddm("4x1", false, 1, "");
    ddm("8x1", false, 1, "");
    ddm("isotropic", true, 1, "");
    ddm("2x1", true, 1, "");
    ddm("4x1", true, 1, "");
    ddm("8x1", true, 1, "");
    ddm("isotropic", true, 0, " (paper's t+d)");
    ddm("4x1", true, 0, " (paper's t+d)");
    ddm("2x2", true, 1, "");
    ddm("4x2", true, 1, "");
    ddm("8x2", true, 1, "");
    auto search = [&](MesoMethod m, int linear, int binary) {
        MesoTechnique t;
        t.method = m;
        t.linear = linear;
        t.binary = binary;
        rows.push_back({m == MesoMethod::Relief ? "relief " + std::to_string(linear) + "+" + std::to_string(binary)
                                                 : "POM " + std::to_string(linear),
                        t, "heights"});
    };
    for (auto [l, b] : {std::pair{8, 4}, {16, 6}, {32, 6}, {64, 8}}) search(MesoMethod::Relief, l, b);
    for (int l : {8, 16, 32, 64}) search(MesoMethod::Pom, l, 0);
    return rows;
}

void iterationColour(int n, unsigned char rgb[3]) {
    static const unsigned char c[5][3] = {{40, 70, 220}, {40, 170, 60}, {210, 40, 40}, {235, 210, 40}, {255, 255, 255}};
    const int k = n < 10 ? 0 : n < 35 ? 1 : n < 60 ? 2 : n <= 100 ? 3 : 4;
    for (int i = 0; i < 3; ++i) rgb[i] = c[k][i];
}

void printMesoTable(std::ostream& out, const MesoTableArgs& args) {
    CsvOut csv(args.csv, "scene,method,mean_iterations,p99_iterations,mean_error_texels,p99_error_texels,wrong_share,"
                         "bytes_uncompressed,bytes_compressed,cpu_ms,gpu_ms");
    const std::vector<MesoRow> rows = mesoRows();
    struct Goal {
        double ddm4 = 0, iso = 0, dmEps = 0, ddm4Err = 0, dmEpsErr = 0, dense4 = 0;
    };
    std::map<std::string, Goal> goals;
    std::ostringstream compression;
    std::unique_ptr<vulkan::Context> ctx;
    if (args.gpu) {
        try {
            vulkan::DeviceOptions o;
            o.device = args.device;
            ctx = std::make_unique<vulkan::Context>(o);
            out << "GPU column: fragment-shader frame time on " << ctx->deviceName() << (ctx->isSoftware() ? " (a CPU device)" : "")
                << ", median of " << args.gpuFrames << " frames after " << args.gpuWarmup << " untimed\n\n";
        } catch (const Error& e) {
            out << "(no GPU column: " << e.what() << ")\n\n";
        }
    }
    for (const MesoScene& scene : mesoScenes(args.dataDir)) {
        const MesoHeightField& hf = scene.field;
        const auto t0 = std::chrono::steady_clock::now();
        // One map set per cone set; the distance map and quadrics are shared.
        const std::map<std::string, MesoMaps> maps = buildConeSetMaps(hf, tableConeSets());
        const double buildS = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const MesoCamera& cam = scene.camera;
        const std::vector<Pixel> px = pixels(cam, hf.layers, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchReference<double>(hf, o, d); });
        out << "Mesostructure scene '" << scene.name << "': " << hf.width << " x " << hf.height << " x " << hf.layers
            << " voxels, " << cam.width << " x " << cam.height << " pixels, maps built in " << std::fixed << std::setprecision(1)
            << buildS << " s (7 cone sets)\n";
        printHeader(out);
        std::vector<std::pair<std::string, Stats>> pictures;
        for (const MesoRow& row : rows) {
            const std::string conesName = row.map.rfind("ddm:", 0) == 0 ? row.map.substr(4) : "4x1";
            const MesoMaps& m = maps.at(conesName);
            Stats st = measure(
                px, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchMeso<float>(m, row.technique, o, d); }, args.minSeconds);
            std::size_t bytes = 0, compressed = 0;
            if (row.map == "distance") bytes = compressed = m.distance.bytes();
            else if (row.map == "heights") bytes = compressed = hf.h.size() * sizeof(float);
            else {
                bytes = m.denseDdmBytes + (row.technique.quadrics ? m.quadrics.bytes() : 0);
                compressed = m.ddm.bytes() + (row.technique.quadrics ? m.quadrics.bytes() : 0);
            }
            if (ctx) st.gpu = gpuFrameMs(*ctx, scene.camera, m, row.technique, args.gpuFrames, args.gpuWarmup);
            printRow(out, csv, scene.name, row.label, st, bytes, compressed);
            Goal& g = goals[scene.name];
            if (row.label == "DDM 4x1 + quadric") {
                g.ddm4 = st.meanIt;
                g.ddm4Err = st.meanErr;
            }
            if (row.label == "conservative isotropic + quadric") g.iso = st.meanIt;
            if (row.label == "distance map, eps 0.02") {
                g.dmEps = st.meanIt;
                g.dmEpsErr = st.meanErr;
            }
            for (const char* shown : {"distance map, 16 steps", "distance map, eps 0.02", "conservative isotropic + quadric",
                                      "DDM 4x1", "DDM 4x1 + quadric", "DDM 8x1 + quadric", "relief 32+6", "POM 32"})
                if (row.label == shown) pictures.push_back({row.label, std::move(st)});
        }
        if (ctx) {
            // What the shading effects cost: the DDM 4x1 + quadric frame with the height
            // field's normal, then with an albedo (the heights as grey), a normal map of the
            // heights (normalMapFromHeights at the table's cubic voxels: one voxel of height
            // over W voxels a tile), and both, each with its mips; five rounds, interleaved, the
            // median of each.
            HeightImage heights{hf.width, hf.height, hf.h};
            std::vector<std::uint8_t> grey(4 * hf.h.size(), 255);
            for (std::size_t i = 0; i < hf.h.size(); ++i)
                grey[4 * i] = grey[4 * i + 1] = grey[4 * i + 2] = static_cast<std::uint8_t>(std::lround(255.0 * std::clamp(double(hf.h[i]) / hf.layers, 0.0, 1.0)));
            const auto albedo = std::make_shared<const MesoAlbedo>(mesoAlbedo(hf.width, hf.height, grey));
            const auto normals = std::make_shared<const MesoAlbedo>(mesoAlbedo(hf.width, hf.height, normalMapFromHeights(heights, 1.0 / hf.width)));
            const MesoRow& ddm = *std::find_if(rows.begin(), rows.end(), [](const MesoRow& r) { return r.label == "DDM 4x1 + quadric"; });
            std::vector<double> runs[4];
            for (int round = 0; round < 5; ++round)
                for (std::size_t k = 0; k < 4; ++k)
                    runs[k].push_back(gpuFrameMs(*ctx, scene.camera, maps.at("4x1"), ddm.technique, args.gpuFrames, args.gpuWarmup, (k & 1) ? albedo : nullptr,
                                                 (k & 2) ? normals : nullptr));
            double ms[4];
            for (std::size_t k = 0; k < 4; ++k) ms[k] = percentile(runs[k], 0.5);
            out << "Shading on '" << scene.name << "' (DDM 4x1 + quadric, GPU ms, images of " << hf.width << " x " << hf.height
                << " with mips): height-field normal " << std::setprecision(2) << ms[0] << "; + albedo " << ms[1] << " (" << ms[1] / ms[0]
                << "x); + normal map " << ms[2] << " (" << ms[2] / ms[0] << "x); + both " << ms[3] << " (" << ms[3] / ms[0] << "x)\n";
        }
        // Compression (Table 3): per cone set, the uncompressed DDM against grid + atlas.
        for (const auto& [name, m] : maps)
            compressionRow(compression, scene.name, name, m.denseDdmBytes, m.ddm);
        // What compression costs in iterations, and the knob that buys them back (compressDdm's
        // maxSpread): DDM 4x1 + quadric on the dense map and on maps compressed with each spread.
        {
            const DirectionalDistanceMap dense = buildDdm(hf, parseConeSet("4x1"));
            const MesoMaps& m4 = maps.at("4x1");
            DdmMarch opt;
            opt.maxIterations = 1024; // as the rows above
            const std::size_t quadricBytes = m4.quadrics.bytes();
            const Stats denseSt = measure(
                px, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchDdm<float>(DenseDdmView{&dense}, dense.cones, hf.layers, &m4.quadrics, o, d, opt); },
                args.minSeconds);
            printRow(out, csv, scene.name, "DDM 4x1 + quadric, dense map", denseSt, dense.bytes() + quadricBytes, dense.bytes() + quadricBytes);
            goals[scene.name].dense4 = denseSt.meanIt;
            for (const float spread : {std::numeric_limits<float>::infinity(), 4.0f, 2.0f, 1.0f, 0.5f, 0.0f}) {
                const CompressedDdm c = compressDdm(dense, 4, spread);
                const Stats st = measure(
                    px, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchDdm<float>(CompressedDdmView{&c}, c.cones, hf.layers, &m4.quadrics, o, d, opt); },
                    args.minSeconds);
                std::ostringstream label;
                label << "DDM 4x1 + quadric, spread " << (std::isinf(spread) ? std::string("inf (paper)") : fixed(static_cast<double>(spread), 1))
                      << (spread == kDefaultCompressionSpread ? " (default)" : "");
                printRow(out, csv, scene.name, label.str(), st, dense.bytes() + quadricBytes, c.bytes() + quadricBytes);
            }
        }
        if (!args.images.empty()) {
            std::filesystem::create_directories(args.images);
            const std::string path = args.images + "/iterations_" + scene.name + ".png";
            writePicture(path, cam, pictures);
            pictureNote(out, path, pictures);
        }
        out << "\n";
    }
    {
        // A non-height-field scene: 16 beads floating over the floor (overhangs), from a mesh.
        std::vector<glm::dvec3> v;
        std::vector<std::array<int, 3>> t;
        for (int by = 0; by < 4; ++by)
            for (int bx = 0; bx < 4; ++bx) appendUvSphere({8.0 + 16 * bx, 8.0 + 16 * by, 7.0 + 2.5 * ((bx + by) % 2)}, 5.0, 12, v, t);
        v.push_back({0, 0, 0}); // the tile: [0, 64]^2, the floor at z = 0
        v.push_back({64, 64, 0});
        const auto t0 = std::chrono::steady_clock::now();
        const MesoSolid solid = mesoSolidFromMesh(v, t, 64, 64, 16, 2);
        const DistanceMap dm = buildSolidDistanceMap(solid);
        std::map<std::string, MesoMaps> ddms; // the solid's maps (DDM compressed, triangle lists) per cone set
        for (const ConeSet cones : {ConeSet::all(), ConeSet{4, 1, false, false}, ConeSet{8, 1, false, false}}) {
            MesoMapOptions o;
            o.cones = cones;
            o.distance = false;
            ddms.emplace(cones.name(), buildMesoSolidMaps(solid, o));
        }
        const double buildS = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const MesoCamera cam = tableCamera(64, 16);
        const std::vector<Pixel> px = pixels(cam, 16, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchSolidReference(solid, o, d); });
        out << "Non-height-field scene 'beads' (a mesh of " << t.size() << " triangles, 16 beads over the floor): 64 x 64 x 16 voxels, "
            << std::fixed << std::setprecision(1) << 100 * solid.solidShare() << " % solid sub-voxels, maps built in " << buildS << " s\n";
        printHeader(out);
        std::vector<std::pair<std::string, Stats>> pictures;
        for (int n : {16, 64}) {
            Stats st = measure(px, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchDistanceMap<float>(dm, o, d, n, -1); }, args.minSeconds);
            printRow(out, csv, "beads", "distance map, " + std::to_string(n) + " steps", st, dm.bytes(), dm.bytes());
            if (n == 16) pictures.push_back({"distance map, 16 steps", std::move(st)});
        }
        {
            Stats st = measure(px, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchDistanceMap<float>(dm, o, d, 256, 0.02); }, args.minSeconds);
            printRow(out, csv, "beads", "distance map, eps 0.02", st, dm.bytes(), dm.bytes());
            pictures.push_back({"distance map, eps 0.02", std::move(st)});
        }
        for (const auto& [name, maps] : ddms) {
            const CompressedDdm& c = maps.ddm;
            const std::size_t triBytes = solid.bytes(); // the triangle lists as the GPU holds them
            for (int rule : {1, 0}) {
                // The GPU's marcher (float), the renderer's loop: kern::dmMesoMarchDdmSolid.
                Stats st = measure(
                    px,
                    [&](const glm::dvec3& o, const glm::dvec3& d) { return marchDdmSolid<float>(CompressedDdmView{&c}, c.cones, solid, o, d, 1024, rule); },
                    args.minSeconds);
                MesoTechnique tq;
                tq.iterations = 1024;
                tq.exitRule = rule;
                if (ctx) st.gpu = gpuFrameMs(*ctx, cam, maps, tq, args.gpuFrames, args.gpuWarmup);
                const std::string label = (name == "isotropic" ? "conservative isotropic" : "DDM " + name.substr(0, 3)) + " + triangles" +
                                          (rule == 0 ? " (paper's t+d)" : "");
                printRow(out, csv, "beads", label, st, maps.denseDdmBytes + triBytes, c.bytes() + triBytes);
                if (rule == 1) pictures.push_back({label, std::move(st)});
            }
            compressionRow(compression, "beads", name, maps.denseDdmBytes, c);
        }
        if (!args.images.empty()) {
            std::filesystem::create_directories(args.images);
            const std::string path = args.images + "/iterations_beads.png";
            writePicture(path, cam, pictures);
            pictureNote(out, path, pictures);
        }
        out << "(beads: exact triangle tests where the DDM is 0, in float as on the GPU; memory with the triangle lists, "
            << solid.bytes() / 1024 << " KiB)\n\n";
    }
    std::ostringstream sparseGoal;
    {
        // A sparse scene (the paper's golden ball, Table 3): one bead floating in a slab twice
        // as deep as the others, nearly all of it empty: where compression pays.
        std::vector<glm::dvec3> v;
        std::vector<std::array<int, 3>> t;
        appendUvSphere({32.0, 32.0, 16.0}, 6.0, 16, v, t);
        v.push_back({0, 0, 0}); // the tile: [0, 64]^2, the floor at z = 0
        v.push_back({64, 64, 0});
        const MesoSolid solid = mesoSolidFromMesh(v, t, 64, 64, 32, 2);
        const ConeSet cones{4, 1, false, false};
        const DirectionalDistanceMap dense = buildSolidDdm(solid, cones);
        const MesoCamera cam = tableCamera(64, 32);
        const std::vector<Pixel> px = pixels(cam, 32, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchSolidReference(solid, o, d); });
        const std::size_t triBytes = t.size() * 36;
        out << "Sparse scene 'ball' (one bead of radius 6 voxels over the floor, " << t.size() << " triangles): 64 x 64 x 32 voxels, "
            << std::fixed << std::setprecision(1) << 100 * solid.solidShare() << " % solid sub-voxels\n";
        printHeader(out);
        const Stats denseSt = measure(
            px, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchDdmSolid(DenseDdmView{&dense}, cones, solid, o, d, 1024, 1); },
            args.minSeconds);
        printRow(out, csv, "ball", "DDM 4x1 + triangles, dense map", denseSt, dense.bytes() + triBytes, dense.bytes() + triBytes);
        sparseGoal << "Goals on 'ball': compression (goal >= 4x) and compressed / dense iterations (goal <= 1.05):";
        for (const float spread : {kDefaultCompressionSpread, 4.0f, std::numeric_limits<float>::infinity()}) {
            const CompressedDdm c = compressDdm(dense, 4, spread);
            const Stats st = measure(
                px, [&](const glm::dvec3& o, const glm::dvec3& d) { return marchDdmSolid(CompressedDdmView{&c}, cones, solid, o, d, 1024, 1); },
                args.minSeconds);
            const std::string name = std::isinf(spread) ? std::string("inf (paper)") : fixed(static_cast<double>(spread), 1);
            printRow(out, csv, "ball", "DDM 4x1 + triangles, spread " + name, st, dense.bytes() + triBytes, c.bytes() + triBytes);
            compressionRow(compression, "ball", "4x1 s " + (std::isinf(spread) ? std::string("inf") : fixed(static_cast<double>(spread), 0)),
                           dense.bytes(), c);
            sparseGoal << " spread " << name << ": " << std::fixed << std::setprecision(1) << c.ratio() << "x at " << std::setprecision(2)
                       << st.meanIt / std::max(denseSt.meanIt, 1e-9) << (std::isinf(spread) ? "" : ";");
        }
        out << "(ball: CPU in double, exact triangle tests where the DDM is 0)\n\n";
    }
    out << "err: |hit - exact hit| in texels over rays both hit; wrong: a miss or false hit, or off by more than a texel.\n";
    out << "CPU: float, one thread, ms per frame; memory: what the method reads (DDM: view cones; + quadrics 48 B/column).\n\n";
    for (const auto& [scene, g] : goals)
        out << "Goals on '" << scene << "': DDM 4x1 + quadric / conservative isotropic + quadric mean iterations = " << std::setprecision(2)
            << g.ddm4 / std::max(g.iso, 1e-9) << " (same exact hits; goal <= 0.6); vs distance map eps 0.02: " << g.ddm4 / std::max(g.dmEps, 1e-9)
            << " at error " << std::setprecision(4) << g.ddm4Err << " vs " << g.dmEpsErr << " texels; compressed (spread "
            << std::setprecision(1) << kDefaultCompressionSpread << ") / dense: " << std::setprecision(3) << g.ddm4 / std::max(g.dense4, 1e-9)
            << " (goal <= 1.05)\n";
    out << sparseGoal.str() << "\n";
    out << "\nCompression (Table 3: uncompressed DDM vs lookup grid + atlas + planes, blocks of 4^3; the shares of blocks stored whole and as planes):\n"
        << "  " << std::left << std::setw(10) << "scene" << std::setw(11) << "cones" << std::right << std::setw(13) << "uncompr." << std::setw(12)
        << "grid" << std::setw(12) << "atlas" << std::setw(12) << "planes" << std::setw(9) << "ratio" << std::setw(9) << "whole" << std::setw(9)
        << "planes" << "\n"
        << compression.str();
    csv.commit();
}

} // namespace dispmap::figures
