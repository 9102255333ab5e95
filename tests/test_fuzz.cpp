// Strict input: only regular files are read, with a size limit per kind; scene JSON is
// depth-limited and its messages quote little of the input; PNG headers are checked before
// decoding; meso options before any map is built; output sizes before anything is made. Then
// fuzz-style tests of every reader here (scene JSON, tile file, mesostructure file, PNG): a
// valid input mutated a few hundred times with a fixed seed, each mutation either loading or
// throwing a dispmap::Error subclass (never another exception, never a crash: the suite also
// runs under ASan/UBSan).
#include <catch2/catch.hpp>

#include "test_files.h"
#include "test_meso_support.h"
#include "test_support.h"

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <functional>
#include <random>
#include <set>
#include <string>
#include <typeinfo>
#include <vector>

#include <png.h>
#include <zlib.h>

#include "dispmap/io/meso_file.h"
#include "dispmap/io/png.h"
#include "dispmap/io/tile_file.h"
#include "dispmap/scene/build.h"
#include "dispmap/scene/meso.h"
#include "dispmap/scene/scene.h"
#include "dispmap/surface/tessellator.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_fuzz {

using namespace dispmap;
using Catch::Contains;
using Bytes = std::vector<unsigned char>;

namespace {
struct TempDir : dmtest::TempDir {
    TempDir() : dmtest::TempDir("dispmap_fuzz_test_") {}
};

void writeText(const std::string& path, const std::string& text) { dmtest::writeBytes(path, Bytes(text.begin(), text.end())); }

// The message of the dispmap::Error that f throws, "" if it returns, or a FAIL for any other
// exception (the contract: every failure of a reader is a dispmap::Error).
std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    } catch (const std::exception& e) {
        FAIL("another exception than dispmap::Error: " << typeid(e).name() << ": " << e.what());
    } catch (...) {
        FAIL("a non-std exception");
    }
    return "";
}

// The message of the E that f throws (E a dispmap::Error), or a note that it threw nothing.
template <class E> std::string messageOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const E& e) {
        return e.what();
    } catch (const std::exception& e) {
        return std::string("<another exception: ") + typeid(e).name() + ": " + e.what() + ">";
    }
    return "<nothing thrown>";
}
#define STRICT_CHECK_THROWS_MSG(expr, E, matcher) CHECK_THAT(messageOf<E>([&] { (void)(expr); }), matcher)

// Seconds f takes.
double secondsOf(const std::function<void()>& f) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A random edit of `b`: flipped bits, a set byte, truncation, a deleted, duplicated or inserted
// run of bytes. Never empty unless b is.
void mutateBytes(Bytes& b, std::mt19937& rng) {
    if (b.empty()) return;
    const auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
    switch (pick(7)) {
    case 0:
    case 1: { // a few flipped bits
        const std::size_t n = 1 + pick(4);
        for (std::size_t i = 0; i < n; ++i) b[pick(b.size())] ^= static_cast<unsigned char>(1u << pick(8));
        break;
    }
    case 2: b[pick(b.size())] = static_cast<unsigned char>(pick(256)); break;
    case 3: b.resize(pick(b.size())); break;
    case 4: { // delete a run
        const std::size_t at = pick(b.size()), n = std::min(b.size() - at, 1 + pick(64));
        b.erase(b.begin() + static_cast<std::ptrdiff_t>(at), b.begin() + static_cast<std::ptrdiff_t>(at + n));
        break;
    }
    case 5: { // duplicate a run
        const std::size_t at = pick(b.size()), n = std::min(b.size() - at, 1 + pick(64));
        const Bytes run(b.begin() + static_cast<std::ptrdiff_t>(at), b.begin() + static_cast<std::ptrdiff_t>(at + n));
        b.insert(b.begin() + static_cast<std::ptrdiff_t>(pick(b.size())), run.begin(), run.end());
        break;
    }
    default: { // insert random bytes, often 0xFF or 0 (huge or zero counts)
        const std::size_t n = 1 + pick(8);
        Bytes run(n);
        for (unsigned char& c : run) c = pick(3) == 0 ? 0xFF : pick(3) == 0 ? 0 : static_cast<unsigned char>(pick(256));
        b.insert(b.begin() + static_cast<std::ptrdiff_t>(pick(b.size())), run.begin(), run.end());
        break;
    }
    }
}

// The tile and mesostructure files end with the CRC-32 of everything before it: recomputed
// after an edit, so that the loaders' other checks are reached.
void resealTrailingCrc(Bytes& b) {
    if (b.size() < 4) return;
    const std::size_t n = b.size() - 4;
    const auto crc = static_cast<std::uint32_t>(crc32(0L, b.data(), static_cast<uInt>(n)));
    for (std::size_t i = 0; i < 4; ++i) b[n + i] = static_cast<unsigned char>(crc >> (8 * i));
}

std::uint32_t be32(const Bytes& b, std::size_t at) {
    return (std::uint32_t{b[at]} << 24) | (std::uint32_t{b[at + 1]} << 16) | (std::uint32_t{b[at + 2]} << 8) | std::uint32_t{b[at + 3]};
}
void putBe32(Bytes& b, std::size_t at, std::uint32_t v) {
    for (std::size_t i = 0; i < 4; ++i) b[at + i] = static_cast<unsigned char>(v >> (8 * (3 - i)));
}

// Recomputes the CRC of every whole PNG chunk after an edit, so that libpng parses what the
// edit made instead of stopping at the first checksum.
void fixPngCrcs(Bytes& b) {
    for (std::size_t at = 8; at + 12 <= b.size();) {
        const std::uint64_t length = be32(b, at);
        if (at + 12 + length > b.size()) break;
        const auto n = static_cast<std::size_t>(length);
        putBe32(b, at + 8 + n, static_cast<std::uint32_t>(crc32(0L, b.data() + at + 4, static_cast<uInt>(n + 4))));
        at += 12 + n;
    }
}

// A PNG chunk: length, type, data, CRC.
void appendChunk(Bytes& png, const char* type, const Bytes& data) {
    Bytes chunk(8 + data.size() + 4);
    putBe32(chunk, 0, static_cast<std::uint32_t>(data.size()));
    std::copy(type, type + 4, chunk.begin() + 4);
    std::copy(data.begin(), data.end(), chunk.begin() + 8);
    putBe32(chunk, 8 + data.size(), static_cast<std::uint32_t>(crc32(0L, chunk.data() + 4, static_cast<uInt>(data.size() + 4))));
    png.insert(png.end(), chunk.begin(), chunk.end());
}

// A valid 8-bit greyscale PNG of width x height black pixels (zlib-compressed rows of zeros:
// a big image is a small file), or, with idatBytes > 0, one that claims that size but whose
// IDAT holds only idatBytes bytes (of the stream of its first rows).
Bytes blackPng(std::uint32_t width, std::uint32_t height, std::size_t idatBytes = 0) {
    Bytes png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    Bytes ihdr(13, 0);
    putBe32(ihdr, 0, width);
    putBe32(ihdr, 4, height);
    ihdr[8] = 8; // bit depth; colour type 0 (grey), deflate, filter 0, no interlacing
    appendChunk(png, "IHDR", ihdr);
    z_stream z{};
    REQUIRE(deflateInit(&z, 9) == Z_OK);
    const Bytes row(std::size_t{width} + 1, 0);
    Bytes out(1 << 16), idat;
    const std::uint32_t rows = idatBytes > 0 ? std::min<std::uint32_t>(height, 16) : height;
    for (std::uint32_t y = 0; y <= rows; ++y) {
        z.next_in = const_cast<Bytef*>(row.data()); // zlib's API is not const; it only reads
        z.avail_in = y < rows ? static_cast<uInt>(row.size()) : 0;
        const int flush = y < rows ? Z_NO_FLUSH : Z_FINISH;
        int rc;
        do {
            z.next_out = out.data();
            z.avail_out = static_cast<uInt>(out.size());
            rc = deflate(&z, flush);
            idat.insert(idat.end(), out.begin(), out.end() - static_cast<std::ptrdiff_t>(z.avail_out));
        } while (z.avail_out == 0 || (flush == Z_FINISH && rc != Z_STREAM_END));
    }
    deflateEnd(&z);
    if (idatBytes > 0) idat.resize(std::min(idat.size(), idatBytes));
    appendChunk(png, "IDAT", idat);
    appendChunk(png, "IEND", {});
    return png;
}

// Random tiles of the given sizes (coefficients in [-1, 1]).
TileSet smallTiles(const std::vector<int>& ks, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
    TileSet ts;
    ts.filter = MipFilter::Haar;
    ts.topologyHash = 0x0123456789ABCDEFull;
    for (int k : ks) {
        Tile t;
        t.k = k;
        t.coefficients.resize(Tile::totalTexels(k));
        for (float& c : t.coefficients) c = uni(rng);
        ts.tiles.push_back(std::move(t));
    }
    return ts;
}

// Small mesostructure maps with every map built: 8 x 8 x 8 voxels, 2x1 cones with shadows.
MesoMaps smallMesoMaps() {
    MesoMapOptions o;
    o.cones = ConeSet{2, 1, true, false};
    o.block = 4;
    return buildMesoMaps(dmtest::hardField(8, 8, 8), o);
}

// Reads a scene file's JSON as `dispmap render` does: a mesostructure scene or a surface scene.
void parseAnyScene(const std::string& text) {
    const nlohmann::json j = parseSceneJson(text, "fuzz.json");
    if (isMesoScene(j)) {
        (void)parseMesoScene(j, "fuzz.json", "");
        return;
    }
    const Scene s = parseSceneDocument(j, "fuzz.json", "");
    // What parses writes back as a scene that parses again (no asymmetry between the rules).
    const Scene again = parseScene(toJson(s), "fuzz.json", "");
    CHECK(toJson(again) == toJson(s));
}

// Where the JSON value that starts at `start` ends (a bracketed value to its matching
// bracket, a string to its closing quote, anything else to the next delimiter).
std::size_t jsonValueEnd(const std::string& text, std::size_t start) {
    const char c = text[start];
    if (c == '"') {
        for (std::size_t i = start + 1; i < text.size(); ++i) {
            if (text[i] == '\\') ++i;
            else if (text[i] == '"') return i + 1;
        }
        return text.size();
    }
    if (c == '[' || c == '{') {
        int depth = 0;
        for (std::size_t i = start; i < text.size(); ++i) {
            if (text[i] == '"') i = jsonValueEnd(text, i) - 1;
            else if (text[i] == '[' || text[i] == '{') ++depth;
            else if ((text[i] == ']' || text[i] == '}') && --depth == 0) return i + 1;
        }
        return text.size();
    }
    const std::size_t end = text.find_first_of(",]} \n", start);
    return end == std::string::npos ? text.size() : std::max(end, start + 1);
}

std::string fileText(const std::string& path) {
    const Bytes b = dmtest::readBytes(path);
    return std::string(b.begin(), b.end());
}
} // namespace

TEST_CASE("strict input: only regular files are read, promptly", "[inputs]") {
    TempDir dir;
    const std::string fifo = dir.file("fifo");
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
    const std::string folder = dir.path.string();
    // Opening a FIFO would wait for a writer and /dev/zero never ends: each is refused at once.
    for (const std::string& path : {fifo, folder, std::string("/dev/zero"), std::string("/dev/null")}) {
        INFO(path);
        const double seconds = secondsOf([&] {
            STRICT_CHECK_THROWS_MSG(loadTiles(path), FileError, Contains("tile file '" + path + "': is not a regular file"));
            STRICT_CHECK_THROWS_MSG(loadMesoMaps(path), FileError, Contains("mesostructure file '" + path + "': is not a regular file"));
            STRICT_CHECK_THROWS_MSG(readHeightPng(path), FileError, Contains("height image '" + path + "': is not a regular file"));
            STRICT_CHECK_THROWS_MSG(readRgbaPng(path), FileError, Contains("is not a regular file"));
            STRICT_CHECK_THROWS_MSG(loadScene(path), FileError, Contains("scene file '" + path + "': is not a regular file"));
            STRICT_CHECK_THROWS_MSG(ControlMesh::fromObjFile(path), FileError, Contains("is not a regular file"));
        });
        CHECK(seconds < 5);
    }
    STRICT_CHECK_THROWS_MSG(loadTiles(folder), FileError, Contains("(a directory)"));
    STRICT_CHECK_THROWS_MSG(loadTiles(fifo), FileError, Contains("(a FIFO (named pipe))"));
    STRICT_CHECK_THROWS_MSG(loadTiles("/dev/zero"), FileError, Contains("(a character device)"));

    SECTION("a scene whose mesh is /dev/zero") {
        writeText(dir.file("s.json"), R"({"mesh": "/dev/zero"})");
        const Scene s = loadScene(dir.file("s.json"));
        STRICT_CHECK_THROWS_MSG(sceneMesh(s), FileError, Contains("'/dev/zero': is not a regular file"));
    }
    SECTION("a file above the kind's limit is refused from its size") {
        writeText(dir.file("big.json"), "{" + std::string(kMaxSceneFileBytes, ' ') + "}");
        STRICT_CHECK_THROWS_MSG(loadScene(dir.file("big.json")), FileError,
                         Contains("scene file") && Contains(std::to_string(kMaxSceneFileBytes + 2) + " bytes is more than the"));
        writeText(dir.file("small.txt"), "0123456789");
        STRICT_CHECK_THROWS_MSG(detail::readFileBytes(dir.file("small.txt"), "test file", 9), FileError,
                         Contains("10 bytes is more than the 9 bytes a test file may have"));
        CHECK(detail::readFileBytes(dir.file("small.txt"), "test file", 10).size() == 10);
    }
    SECTION("nothing is written over a FIFO or device: it is left as it was") {
        STRICT_CHECK_THROWS_MSG(saveTiles(smallTiles({1}, 1), fifo), FileError, Contains("exists and is not a regular file (a FIFO"));
        struct stat st {};
        REQUIRE(::stat(fifo.c_str(), &st) == 0);
        CHECK(S_ISFIFO(st.st_mode));
        CHECK(dir.entries() == std::set<std::string>{"fifo"});
    }
}

TEST_CASE("strict input: scene JSON nests at most 64 deep, and messages quote little of it", "[inputs][scene]") {
    // 100,000 nested arrays overflowed the stack of the serialiser: refused from the text.
    const std::string deep(100000, '[');
    STRICT_CHECK_THROWS_MSG(parseScene(deep, "deep.json", ""), SceneError,
                     Contains("scene 'deep.json': invalid JSON: arrays and objects nest deeper than 64 levels (at byte 64)"));
    STRICT_CHECK_THROWS_MSG(parseScene(std::string(70, '{'), "deep.json", ""), SceneError, Contains("deeper than 64"));
    // Brackets in strings and comments do not count; 64 levels are fine for the parser.
    CHECK_NOTHROW(parseScene("{\"mesh\": \"" + std::string(1000, '[') + "\"}", "s.json", ""));
    CHECK_NOTHROW(parseScene("// " + std::string(1000, '[') + "\n/* " + std::string(1000, '{') + " */ {}", "c.json", ""));
    STRICT_CHECK_THROWS_MSG(parseScene("{\"effects\": " + std::string(63, '[') + std::string(63, ']') + "}", "s.json", ""), SceneError,
                     Contains("effects: expected an object, got [[[["));

    // A wrong type quotes ~80 characters of the value, however big it is.
    std::string big = "[";
    for (int i = 0; i < 100000; ++i) big += (i ? "," : "") + std::to_string(i);
    big += "]";
    const std::string m = messageOf<SceneError>([&] { (void)parseScene("{\"mesh\": " + big + "}", "big.json", ""); });
    CHECK_THAT(m, Contains("mesh: expected a string, got [0,1,2,3,"));
    CHECK(m.size() < 200);
    const std::string key = messageOf<SceneError>([&] { (void)parseScene("{\"" + std::string(100000, 'k') + "\": 1}", "k.json", ""); });
    CHECK_THAT(key, Contains("unknown key 'kkkk") && Contains("...' (known: mesh"));
    CHECK(key.size() < 400);
    const std::string value =
        messageOf<SceneError>([&] { (void)parseScene("{\"effects\": {\"normals\": \"" + std::string(100000, 'n') + "\"}}", "v.json", ""); });
    CHECK(value.size() < 300);
    const std::string parse = messageOf<SceneError>([&] { (void)parseScene("{\"mesh\": \"" + std::string(100000, 'x'), "p.json", ""); });
    CHECK_THAT(parse, Contains("invalid JSON"));
    CHECK(parse.size() < 500);
    STRICT_CHECK_THROWS_MSG(parseScene("{\"mesh\": \"" + std::string(5000, 'x') + ".obj\"}", "p.json", ""), SceneError,
                     Contains("mesh: a path of 5004 characters, longer than 4096"));
}

TEST_CASE("strict input: one range rule for scene files and renderers; non-finite results refused", "[inputs][scene]") {
    using Row = std::pair<const char*, const char*>;
    const std::vector<Row> rows = {
        {R"({"camera": {"near": 1e-300, "far": 1e300}})", "camera.near: 1e-300 is below 1.1754943508222875e-38"},
        {R"({"camera": {"near": 1e-30, "far": 1e300}})", "camera.far: far / near = inf exceeds 1e+07"},
        {R"({"camera": {"near": 0.001, "far": 1e6}})", "camera.far: far / near = 1e+09 exceeds 1e+07"},
        {R"({"camera": {"fovY": 1e-300}})", "camera.fovY: 1e-300 degrees is below 0.01"},
        {R"({"camera": {"eye": [1e300, 0, 0]}})", "camera.eye[0]: 1e+300 is out of range (must be <= 1e+18)"},
        {R"({"lights": [{"color": [1e300, 1, 1]}]})", "lights[0].color[0]: 1e+300 is out of range (must be <= 1e+18)"},
        {R"({"lights": [{"direction": [1e300, 0, 0]}]})", "lights[0].direction[0]: 1e+300 is out of range"},
        {R"({"ambient": 1e300})", "ambient: 1e+300 is out of range (must be <= 1e+18)"},
        {R"({"effects": {"tessellation": {"value": 1e300}}})", "effects.tessellation.value: 1e+300 is out of range"},
        {R"({"displacement": {"scale": 1e308}})", "displacement.scale: |offset| + |scale| = 1e+308 exceeds 1e+06"},
        {R"({"displacement": {"scale": 1, "offset": -1e7}})", "displacement.scale: |offset| + |scale| = 10000001 exceeds"},
        {R"({"resolution": [4294967297, 240]})", "resolution[0]: 4294967297 is out of range [1, 4096]"},
    };
    for (const auto& [json, message] : rows) {
        INFO(json);
        STRICT_CHECK_THROWS_MSG(parseScene(json, "bad.json", ""), SceneError, Contains(std::string("scene 'bad.json': ") + message));
    }
    // The renderers' check is the same rule, with the same key names.
    SurfaceDraw d;
    d.camera.nearPlane = 1e-300;
    d.camera.farPlane = 1e300;
    STRICT_CHECK_THROWS_MSG(checkSurfaceDraw(d), ArgumentError, Contains("camera.near: 1e-300 is below"));
    STRICT_CHECK_THROWS_MSG(checkCamera(d.camera), ArgumentError, Contains("camera.near: 1e-300 is below"));
    d = SurfaceDraw{};
    d.width = 0;
    STRICT_CHECK_THROWS_MSG(checkSurfaceDraw(d), ArgumentError, Contains("resolution[0]: 0 is out of range [1, 4096] (image size 0 x 240)"));
    d = SurfaceDraw{};
    d.effects.maxFactor = 65;
    STRICT_CHECK_THROWS_MSG(checkSurfaceDraw(d), ArgumentError, Contains("effects.tessellation.max: 65 is out of range (must be <= 64)"));
    d = SurfaceDraw{};
    d.lights[0].direction = glm::dvec3(0);
    STRICT_CHECK_THROWS_MSG(checkSurfaceDraw(d), ArgumentError, Contains("lights[0].direction: is the zero vector"));
    CHECK_NOTHROW(checkSurfaceDraw(SurfaceDraw{}));
    CHECK_NOTHROW(checkSurfaceDraw(defaultScene()));
    // The tile builders apply the displacement rule too (`dispmap tiles --scale 1e308`).
    SceneDisplacement huge;
    huge.scale = 1e308;
    const ControlMesh cube = dmtest::shape("catmark_cube");
    STRICT_CHECK_THROWS_MSG(displacementTiles(cube, huge), ArgumentError, Contains("displacement.scale: |offset| + |scale| = 1e+308"));
}

TEST_CASE("strict input: PNG headers are checked before anything is decoded", "[inputs][image]") {
    TempDir dir;
    const std::string path = dir.file("h.png");
    // A valid black 8 x 4 image reads.
    dmtest::writeBytes(path, blackPng(8, 4));
    CHECK(readHeightPng(path).values == std::vector<float>(32, 0.0f));

    // A small file that claims 16384^2 pixels: refused from its header (libpng would allocate
    // 256 MiB of rows first), in milliseconds.
    dmtest::writeBytes(path, blackPng(16384, 16384, 64));
    const double seconds = secondsOf([&] {
        STRICT_CHECK_THROWS_MSG(readHeightPng(path), FileError,
                         Contains("truncated or corrupt: 64 bytes of image data for 16384 x 16384 pixels, which need at least"));
        STRICT_CHECK_THROWS_MSG(readRgbaPng(path), FileError, Contains("truncated or corrupt"));
    });
    CHECK(seconds < 1);

    // A valid image above the caller's limit (a mesostructure's 4096 per side): refused from the
    // header with the caller's hint, not decoded.
    dmtest::writeBytes(path, blackPng(4097, 8));
    CHECK(readHeightPng(path).width == 4097);
    STRICT_CHECK_THROWS_MSG(readHeightPng(path, kMaxMesoSize, " (give --size)"), FileError,
                     Contains("too large (4097 x 8; at most 4096 per side) (give --size)"));
    STRICT_CHECK_THROWS_MSG(readRgbaPng(path, 4096), FileError, Contains("too large (4097 x 8; at most 4096 per side)"));

    // Bit depth and colour type that do not go together.
    Bytes bad = blackPng(8, 4);
    bad[24] = 3;
    fixPngCrcs(bad);
    dmtest::writeBytes(path, bad);
    STRICT_CHECK_THROWS_MSG(readHeightPng(path), FileError, Contains("bit depth 3 is invalid for colour type 0"));
    bad[24] = 8;
    bad[25] = 5;
    fixPngCrcs(bad);
    dmtest::writeBytes(path, bad);
    STRICT_CHECK_THROWS_MSG(readHeightPng(path), FileError, Contains("unknown colour type 5"));

    SECTION("a mesostructure scene with an image above 4096 and no size to filter it to") {
        dmtest::writeBytes(path, blackPng(4100, 4100));
        const MesoSceneDesc s = parseMesoScene(nlohmann::json::parse(R"({"mesostructure": {"height": "h.png"}})"), "m.json", dir.path.string());
        STRICT_CHECK_THROWS_MSG(buildMesoSceneMaps(s), FileError, Contains("too large (4100 x 4100; at most 4096 per side)"));
    }
}

TEST_CASE("strict input: mesostructure options are checked before any map is built", "[inputs][meso]") {
    MesoMapOptions o;
    CHECK_THAT(mesoBuildProblem(510, 510, 16, o), Contains("compression block 4 must be in 1..32 and divide the width, height and layers (510 x 510 x 16)"));
    CHECK(mesoBuildProblem(512, 512, 16, o).empty());
    o.block = 64;
    CHECK_THAT(mesoBuildProblem(512, 512, 16, o), Contains("compression block 64"));
    o.block = 4;
    o.compressionSpread = -1.0f;
    CHECK_THAT(mesoBuildProblem(512, 512, 16, o), Contains("compression spread -1.000000 must be >= 0 voxels"));
    o.compressionSpread = std::numeric_limits<float>::quiet_NaN();
    CHECK_THAT(mesoBuildProblem(512, 512, 16, o), Contains("must be >= 0 voxels"));
    o.compressionSpread = std::numeric_limits<float>::infinity(); // the paper's rule
    CHECK(mesoBuildProblem(512, 512, 16, o).empty());
    o.compressionSpread = kDefaultCompressionSpread;
    o.ddm = false; // no DDM: the block is not used
    CHECK(mesoBuildProblem(510, 510, 16, o).empty());
    o = MesoMapOptions{};
    o.cones = ConeSet{3, 1, false, false};
    CHECK_THAT(mesoBuildProblem(64, 64, 16, o), Contains("not supported"));
    o = MesoMapOptions{};
    CHECK_THAT(mesoBuildProblem(4096, 4096, 256, o), Contains("MiB while they are built, more than 4096 MiB"));
    CHECK_THAT(mesoBuildProblem(64, 64, 1, o), Contains("layers is out of range"));

    const auto parse = [](const char* json) { return parseMesoScene(nlohmann::json::parse(json), "m.json", ""); };
    using Row = std::pair<const char*, const char*>;
    const std::vector<Row> rows = {
        {R"({"mesostructure": {"size": 62}})", "compression block 4 must be in 1..32 and divide"},
        {R"({"mesostructure": {"block": 3}})", "compression block 3"},
        {R"({"mesostructure": {"block": 0}})", "'mesostructure.block' 0 is not in 1..32"},
        {R"({"mesostructure": {"function": "noise"}})", "unknown function 'noise'"},
        {R"({"mesostructure": {"size": 0}})", "'mesostructure.size' 0 out of range"},
        {R"({"mesostructure": {"depth": 17}})", "'mesostructure.depth' 17"},
        {R"({"mesostructure": {"cones": "3x1"}})", "not supported"},
        {R"({"mesostructure": {}, "effects": {"iterations": 1000000000}})", "at most 4096"},
        {R"({"mesostructure": {}, "effects": {"technique": "relief", "linear": 100000}})", "at most 4096, 1024 and 32"},
        {R"({"mesostructure": {}, "resolution": [4294967297, 240]})", "'resolution' 4294967297 x 240 is out of range"},
        {R"({"mesostructure": {}, "camera": {"fov": 0}})", "'camera.fov' 0"},
        {R"({"mesostructure": {}, "camera": {"eye": [0, 0, -1]}})", "above the plane"},
        {R"({"mesostructure": {}, "camera": {"eye": [0, 0, 1], "target": [0, 0, 1]}})", "the same point"},
        {R"({"mesostructure": {}, "light": [0, 0, 0]})", "'light' is the zero vector"},
        {R"({"mesostructure": {}, "light": [1, 0, -1], "effects": {"shadows": true}})", "above the horizon"},
        {R"({"mesostructure": {}, "camera": {"eye": [1e300, 0, 1]}})", "beyond +-1e+18"},
        {R"({"mesostructure": {}, "tile": 1e300})", "beyond +-1e+18"},
    };
    for (const auto& [json, message] : rows) {
        INFO(json);
        STRICT_CHECK_THROWS_MSG(parse(json), ArgumentError, Contains("m.json: ") && Contains(message));
    }
    CHECK_NOTHROW(parse(R"({"mesostructure": {}})"));
    // Without a DDM (relief) the block does not have to divide.
    CHECK_NOTHROW(parse(R"({"mesostructure": {"size": 62}, "effects": {"technique": "relief"}})"));
}

TEST_CASE("strict input: a tessellation's size is known, and limited, before it is made", "[inputs][tessellate]") {
    const ControlMesh mesh = dmtest::shape("catmark_nonquads");
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 3), dmtest::roughSource);
    const BaseSurface base(mesh);
    const DisplacedSurface ds(base, tiles);
    for (Spacing spacing : {Spacing::FractionalEven, Spacing::Integer})
        for (double f : {1.0, 1.5, 3.0, 5.5, 8.0}) {
            INFO("factor " << f << ", spacing " << toString(spacing));
            TessellateOptions o;
            o.spacing = spacing;
            const Tessellator t(ds, uniformTessFactors(base, f), o);
            const TessellationSize size = t.estimate();
            const TriangleMesh m = t.tessellate();
            CHECK(size.triangles == static_cast<std::uint64_t>(m.triangleCount()));
            CHECK(size.vertices >= static_cast<std::uint64_t>(m.vertexCount()));
            CHECK(size.vertices <= 4 * static_cast<std::uint64_t>(m.vertexCount()) + 16); // shared points counted per tile
        }
    {
        const Tessellator t(ds, distanceTessFactors(base, glm::dvec3(0, 0, 4), 10.0), TessellateOptions{});
        CHECK(t.estimate().triangles == static_cast<std::uint64_t>(t.tessellate().triangleCount()));
    }
    // `dispmap tessellate --factor 1000 --max-factor 1000` grew past 1.6 GB: refused at once.
    TessellateOptions big;
    big.maxFactor = 1000;
    const Tessellator t(ds, uniformTessFactors(base, 1000), big);
    CHECK(t.estimate().triangles > 30'000'000);
    const double seconds = secondsOf([&] {
        STRICT_CHECK_THROWS_MSG(t.tessellate(), ArgumentError, Contains("MiB, more than the limit of 4096 MiB: lower the factors"));
    });
    CHECK(seconds < 1);
}

TEST_CASE("strict input: a damaged mesostructure file is named as one", "[inputs][meso]") {
    TempDir dir;
    const std::string path = dir.file("m.dmm");
    saveMesoMaps(smallMesoMaps(), path);
    Bytes b = dmtest::readBytes(path);
    b.resize(b.size() / 2);
    resealTrailingCrc(b);
    dmtest::writeBytes(path, b);
    const std::string m = messageOf<FileError>([&] { (void)loadMesoMaps(path); });
    CHECK_THAT(m, Contains("mesostructure file '" + path + "': truncated at byte"));
    CHECK_THAT(m, !Contains("tile file"));
}

TEST_CASE("fuzz: scene JSON", "[inputs][fuzz]") {
    std::vector<std::string> seeds = {defaultSceneJson(), toJson(defaultScene())};
    for (const char* file : {"nonquads_accurate.json", "meso_bricks_shadows.json", "meso_grating_relief.json", "unknown_effect.json"})
        seeds.push_back(fileText(dmtest::dataPath(std::string("scenes/") + file)));
    const std::vector<std::string> tokens = {
        "[", "]", "{", "}", ",", ":", "\"", "1e999", "-1e999", "NaN", "\"NaN\"", "Infinity", "-Infinity", "null", "true", "[]", "{}",
        "1e308", "-1e308", "1e-320", "-0", "0", "4294967297", "18446744073709551616", "-9223372036854775809", "1.5", "65", "1e300",
        "\"\\u0000\"", "\"\\ud800\"", "\"\xff\xfe\"", "//", "/*", "*/", "\"" + std::string(3000, 'a') + "\"", std::string(80, '['),
        "[1, 2, 3]", "[0, 0, 0]", "\"builtin:torus\"", "\"isotropic\"", "\"8x2\"", "\"ddm\"", "\"relief\"", "-1", "1e9",
    };
    std::mt19937 rng(20240611);
    const auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
    int loaded = 0, refused = 0, unparsed = 0;
    std::size_t longest = 0;
    for (int iteration = 0; iteration < 800; ++iteration) {
        std::string text = seeds[pick(seeds.size())];
        // Mostly values replaced (valid JSON that reaches the readers' checks), else raw edits.
        for (std::size_t edits = 1 + pick(2); edits > 0; --edits) {
            switch (pick(6)) {
            case 0:
            case 1:
            case 2: { // a value (or an array element) replaced by a token
                const std::size_t at = text.find_first_of(pick(2) == 0 ? ":" : ",[", pick(text.size()));
                if (at == std::string::npos) break;
                const std::size_t start = text.find_first_not_of(" \n", at + 1);
                if (start == std::string::npos) break;
                text.replace(start, jsonValueEnd(text, start) - start, tokens[pick(tokens.size())]);
                break;
            }
            case 3: text.insert(pick(text.size() + 1), tokens[pick(tokens.size())]); break;
            default: {
                Bytes b(text.begin(), text.end());
                mutateBytes(b, rng);
                text.assign(b.begin(), b.end());
                break;
            }
            }
        }
        INFO("iteration " << iteration << ": " << text.substr(0, 300));
        const std::string message = errorOf([&] { parseAnyScene(text); });
        (message.empty() ? loaded : refused) += 1;
        unparsed += message.find("invalid JSON") != std::string::npos;
        longest = std::max(longest, message.size());
        // No message quotes the input at length (the 3000-character string, an 80-deep array).
        CHECK(message.size() < 700);
    }
    // Deep nesting, and the same deep nesting inside a meso scene.
    CHECK_THAT(errorOf([] { parseAnyScene(std::string(100000, '[') + std::string(100000, ']')); }), Contains("deeper than 64"));
    CHECK_THAT(errorOf([] { parseAnyScene("{\"mesostructure\": " + std::string(100000, '{')); }), Contains("deeper than 64"));
    // Every truncation of the seeds.
    for (const std::string& seed : seeds)
        for (std::size_t n = 0; n < seed.rfind('}'); n += 3) CHECK(!errorOf([&] { parseAnyScene(seed.substr(0, n)); }).empty());
    INFO("loaded " << loaded << ", refused " << refused << " (" << unparsed << " as invalid JSON), longest message " << longest);
    // The mutations reach the readers' checks, not only the parser.
    CHECK(loaded > 20);
    CHECK(refused - unparsed > 100);
    CHECK(unparsed > 100);
}

TEST_CASE("fuzz: tile file", "[inputs][fuzz]") {
    TempDir dir;
    const std::string path = dir.file("t.dmt");
    saveTiles(smallTiles({1, 2, 3, 1, 2}, 5), path);
    const Bytes good = dmtest::readBytes(path);
    std::mt19937 rng(77);
    int loaded = 0;
    for (int iteration = 0; iteration < 400; ++iteration) {
        Bytes b = good;
        for (int edits = 1 + iteration % 3; edits > 0; --edits) mutateBytes(b, rng);
        if (iteration % 2 == 0) resealTrailingCrc(b); // past the checksum, to the other checks
        dmtest::writeBytes(path, b);
        INFO("iteration " << iteration << ", " << b.size() << " bytes");
        TileSet ts;
        const std::string message = errorOf([&] { ts = loadTiles(path); });
        if (!message.empty()) {
            CHECK_THAT(message, Contains("tile file '" + path + "'"));
            continue;
        }
        ++loaded;
        for (const Tile& t : ts.tiles) {
            REQUIRE(t.coefficients.size() == Tile::totalTexels(t.k));
            for (float c : t.coefficients) REQUIRE(std::isfinite(c));
        }
    }
    CHECK(loaded > 0); // resealed edits of coefficients load
}

TEST_CASE("fuzz: mesostructure file", "[inputs][fuzz]") {
    TempDir dir;
    const std::string path = dir.file("m.dmm");
    saveMesoMaps(smallMesoMaps(), path);
    const Bytes good = dmtest::readBytes(path);
    std::mt19937 rng(4242);
    int loaded = 0;
    for (int iteration = 0; iteration < 300; ++iteration) {
        Bytes b = good;
        for (int edits = 1 + iteration % 3; edits > 0; --edits) mutateBytes(b, rng);
        if (iteration % 4 != 0) resealTrailingCrc(b);
        dmtest::writeBytes(path, b);
        INFO("iteration " << iteration << ", " << b.size() << " bytes");
        MesoMaps m;
        const std::string message = errorOf([&] { m = loadMesoMaps(path); });
        if (!message.empty()) {
            CHECK_THAT(message, Contains("mesostructure file '" + path + "'"));
            continue;
        }
        ++loaded;
        REQUIRE(m.field.h.size() == static_cast<std::size_t>(m.field.width) * static_cast<std::size_t>(m.field.height));
        REQUIRE(m.distance.d.size() == m.field.h.size() * static_cast<std::size_t>(m.field.layers));
        REQUIRE(m.ddm.wordsValid());
    }
    CHECK(loaded > 0);
}

TEST_CASE("fuzz: PNG", "[inputs][fuzz]") {
    TempDir dir;
    const std::string grey = dir.file("grey.png"), rgba = dir.file("rgba.png"), path = dir.file("fuzz.png");
    HeightImage img;
    img.width = 9;
    img.height = 7;
    std::mt19937 rng(99);
    for (int i = 0; i < 63; ++i) img.values.push_back(static_cast<float>(rng() % 65536) / 65535.0f);
    writeHeightPng16(grey, img);
    std::vector<std::uint8_t> px(5 * 4 * 4);
    for (std::uint8_t& p : px) p = static_cast<std::uint8_t>(rng());
    writeRgbaPng(rgba, 5, 4, px.data());
    const std::vector<Bytes> seeds = {dmtest::readBytes(grey), dmtest::readBytes(rgba), blackPng(6, 5)};
    const auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
    int loaded = 0;
    for (int iteration = 0; iteration < 500; ++iteration) {
        Bytes b = seeds[pick(seeds.size())];
        if (iteration % 5 == 0 && b.size() > 29) {
            // The header's fields: sizes (up to huge), bit depth, colour type, interlacing.
            const std::size_t field = 16 + pick(13);
            b[field] = static_cast<unsigned char>(pick(3) == 0 ? 0xFF : pick(17));
        } else {
            for (std::size_t edits = 1 + pick(2); edits > 0; --edits) mutateBytes(b, rng);
        }
        if (iteration % 3 != 0) fixPngCrcs(b); // past libpng's checksums, into its parser
        dmtest::writeBytes(path, b);
        INFO("iteration " << iteration << ", " << b.size() << " bytes");
        HeightImage h;
        const std::string message = errorOf([&] { h = readHeightPng(path); });
        if (message.empty()) {
            ++loaded;
            REQUIRE(h.values.size() == static_cast<std::size_t>(h.width) * static_cast<std::size_t>(h.height));
            for (float v : h.values) REQUIRE((v >= 0.0f && v <= 1.0f));
        } else {
            CHECK_THAT(message, Contains("height image '" + path + "'"));
        }
        RgbaImage c;
        if (errorOf([&] { c = readRgbaPng(path); }).empty())
            REQUIRE(c.rgba.size() == 4 * static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height));
    }
    CHECK(loaded > 0);
}

#undef STRICT_CHECK_THROWS_MSG

} // namespace dmtest_fuzz
