// Tile file (tile_file.h): bit-exact round trips, and every kind of damaged file or invalid
// tile set rejected with the right exception, without leaving partial files behind.
#include <catch2/catch.hpp>

#include "test_files.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <zlib.h>

#include "dispmap/io/tile_file.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_tile_file {

namespace fs = std::filesystem;
using dispmap::ArgumentError;
using dispmap::FileError;
using dispmap::MipFilter;
using dispmap::Tile;
using dispmap::TileSet;

using dmtest::readBytes;
using dmtest::writeBytes;
struct TempDir : dmtest::TempDir {
    TempDir() : dmtest::TempDir("dispmap_tile_file_test_") {}
};

namespace {


// Recomputes the trailing CRC-32 after a deliberate edit, so that the loader's other checks
// are reached.
void reseal(std::vector<unsigned char>& bytes) {
    const std::size_t n = bytes.size() - 4;
    const auto crc = static_cast<std::uint32_t>(crc32(0L, bytes.data(), static_cast<uInt>(n)));
    for (std::size_t i = 0; i < 4; ++i)
        bytes[n + i] = static_cast<unsigned char>(crc >> (8 * i));
}

// A tile of size 2^k with random coefficients mixing ordinary, negative, subnormal, tiny,
// huge and signed-zero values, and random valid size differences.
Tile randomTile(int k, std::mt19937& rng) {
    Tile t;
    t.k = k;
    std::uniform_int_distribution<int> diff(0, k - dispmap::kMinTileLog2);
    for (auto& d : t.sizeDifferences)
        d = static_cast<std::uint8_t>(diff(rng));
    std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
    std::uniform_int_distribution<int> kind(0, 7);
    t.coefficients.resize(Tile::totalTexels(k));
    for (float& c : t.coefficients) {
        switch (kind(rng)) {
        case 0:
            c = uni(rng) * 1e-38f;
            break; // subnormal range
        case 1:
            c = uni(rng) * std::numeric_limits<float>::max();
            break; // huge
        case 2:
            c = std::numeric_limits<float>::denorm_min() * uni(rng);
            break; // tiniest (or 0)
        case 3:
            c = -0.0f;
            break;
        case 4:
            c = uni(rng) * 1e20f;
            break;
        default:
            c = uni(rng);
            break;
        }
    }
    return t;
}

// A tile set with the given tile sizes.
TileSet randomTiles(const std::vector<int>& ks, MipFilter filter, std::uint64_t hash, unsigned seed) {
    std::mt19937 rng(seed);
    TileSet set;
    set.filter = filter;
    set.topologyHash = hash;
    for (int k : ks)
        set.tiles.push_back(randomTile(k, rng));
    return set;
}

// Bit-for-bit equality of two tile sets (floats compared by their bit patterns).
void requireIdentical(const TileSet& a, const TileSet& b) {
    REQUIRE(a.filter == b.filter);
    REQUIRE(a.topologyHash == b.topologyHash);
    REQUIRE(a.tiles.size() == b.tiles.size());
    for (std::size_t i = 0; i < a.tiles.size(); ++i) {
        INFO("tile " << i);
        REQUIRE(a.tiles[i].k == b.tiles[i].k);
        REQUIRE(a.tiles[i].sizeDifferences == b.tiles[i].sizeDifferences);
        REQUIRE(a.tiles[i].coefficients.size() == b.tiles[i].coefficients.size());
        std::size_t differing = 0;
        for (std::size_t j = 0; j < a.tiles[i].coefficients.size(); ++j)
            if (std::bit_cast<std::uint32_t>(a.tiles[i].coefficients[j]) !=
                std::bit_cast<std::uint32_t>(b.tiles[i].coefficients[j]))
                ++differing;
        REQUIRE(differing == 0);
    }
}

// A small valid tile file's bytes (two tiles, k = 1 and 2).
std::vector<unsigned char> smallFile(const TempDir& dir) {
    const std::string path = dir.file("small.dmt");
    dispmap::saveTiles(randomTiles({1, 2}, MipFilter::BWavelet, 0xFEEDFACECAFEBEEFull, 7), path);
    return readBytes(path);
}

} // namespace

TEST_CASE("tile file: round trip is bit for bit", "[tile_file]") {
    TempDir dir;
    const std::string path = dir.file("tiles.dmt");
    for (MipFilter filter : {MipFilter::Haar, MipFilter::BWavelet}) {
        const TileSet saved = randomTiles({3, 1, 8, 2, 5, 4, 7, 6, 1, 3}, filter, 0x0123456789ABCDEFull,
                                          static_cast<unsigned>(filter));
        dispmap::saveTiles(saved, path);
        requireIdentical(dispmap::loadTiles(path), saved);
    }
    SECTION("an empty tile set") {
        TileSet empty;
        empty.topologyHash = ~std::uint64_t{0};
        dispmap::saveTiles(empty, path);
        requireIdentical(dispmap::loadTiles(path), empty);
    }
    SECTION("the layout matches the documented table") {
        const TileSet one = randomTiles({1}, MipFilter::BWavelet, 0x1122334455667788ull, 3);
        dispmap::saveTiles(one, path);
        const std::vector<unsigned char> b = readBytes(path);
        REQUIRE(b.size() == 16 + 13 + 5 + 4 * Tile::totalTexels(1) + 4);
        REQUIRE(std::string(b.begin(), b.begin() + 8) == std::string("DMTILES\0", 8));
        REQUIRE(b[8] == 1);   // version, little-endian
        REQUIRE(b[12] == 13); // header byte count
        REQUIRE(b[16] == 1);  // BWavelet
        REQUIRE(b[17] == 1);  // one tile
        REQUIRE(b[21] == 0x88);
        REQUIRE(b[28] == 0x11);
        REQUIRE(b[29] == 1); // k
        const auto first = std::bit_cast<std::uint32_t>(one.tiles[0].coefficients[0]);
        REQUIRE(b[34] == (first & 0xFF));
        REQUIRE(b[37] == (first >> 24));
    }
    SECTION("a longer header from a compatible writer is skipped") {
        const TileSet one = randomTiles({2}, MipFilter::Haar, 42, 4);
        dispmap::saveTiles(one, path);
        std::vector<unsigned char> b = readBytes(path);
        b[12] = 15; // header byte count 13 -> 15, two reserved bytes after the topology hash
        b.insert(b.begin() + 29, {0xAB, 0xCD});
        reseal(b);
        writeBytes(path, b);
        requireIdentical(dispmap::loadTiles(path), one);
    }
    REQUIRE(dir.entries() == std::set<std::string>{"tiles.dmt"}); // no temporaries left
}

TEST_CASE("tile file: every truncation is rejected", "[tile_file]") {
    TempDir dir;
    const std::vector<unsigned char> full = smallFile(dir);
    const std::string path = dir.file("cut.dmt");
    for (std::size_t n = 0; n < full.size(); ++n) {
        INFO("prefix of " << n << " of " << full.size() << " bytes");
        writeBytes(path,
                   std::vector<unsigned char>(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(n)));
        REQUIRE_THROWS_AS(dispmap::loadTiles(path), FileError);
        REQUIRE_THROWS_WITH(dispmap::loadTiles(path),
                            Catch::Contains("truncated at byte " + std::to_string(n)));
    }
}

TEST_CASE("tile file: a changed byte is detected", "[tile_file]") {
    TempDir dir;
    const std::vector<unsigned char> full = smallFile(dir);
    const std::string path = dir.file("flipped.dmt");
    for (std::size_t pos = 0; pos < full.size(); ++pos) {
        for (int mask : {0x01, 0x80, 0xFF}) {
            INFO("byte " << pos << " xor " << mask);
            std::vector<unsigned char> b = full;
            b[pos] = static_cast<unsigned char>(b[pos] ^ mask);
            writeBytes(path, b);
            REQUIRE_THROWS_AS(dispmap::loadTiles(path), FileError);
            if (pos >= 39) // in the coefficients or the checksum: only the checksum can tell
                REQUIRE_THROWS_WITH(dispmap::loadTiles(path), Catch::Contains("checksum mismatch"));
        }
    }
}

TEST_CASE("tile file: malformed files are rejected with a reason", "[tile_file]") {
    TempDir dir;
    const std::vector<unsigned char> good = smallFile(dir);
    const std::string path = dir.file("bad.dmt");
    const auto loadEdited = [&](const auto& edit, bool resealed) {
        std::vector<unsigned char> b = good;
        edit(b);
        if (resealed) reseal(b);
        writeBytes(path, b);
        return dispmap::loadTiles(path);
    };

    REQUIRE_THROWS_WITH(dispmap::loadTiles(dir.file("missing.dmt")),
                        Catch::Contains("cannot open") && Catch::Contains("missing.dmt"));
    REQUIRE_THROWS_AS(dispmap::loadTiles(dir.file("missing.dmt")), FileError);
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b[0] = 'X'; }, false), Catch::Contains("bad magic"));
    REQUIRE_THROWS_AS(loadEdited([](auto& b) { b[0] = 'X'; }, false), FileError);
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b[8] = 2; }, true),
                        Catch::Contains("version 2") && Catch::Contains("supports version 1"));
    REQUIRE_THROWS_AS(loadEdited([](auto& b) { b[8] = 2; }, true), FileError);
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b[12] = 12; }, true), Catch::Contains("header size 12"));
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b[16] = 2; }, true),
                        Catch::Contains("unknown mip filter 2"));
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b[29] = 0; }, true), Catch::Contains("tile 0: k = 0"));
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b[34] = 9; }, true), Catch::Contains("tile 1: k = 9"));
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b[30] = 1; }, true), Catch::Contains("size difference 1"));
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b[17] = 0xFF; }, true), Catch::Contains("truncated"));
    REQUIRE_THROWS_WITH(loadEdited([](auto& b) { b.insert(b.end() - 4, 0); }, true),
                        Catch::Contains("1 unexpected bytes"));
    const auto nanAt = [](std::size_t at) {
        return [at](auto& b) {
            const auto nan = std::bit_cast<std::uint32_t>(std::numeric_limits<float>::quiet_NaN());
            for (std::size_t i = 0; i < 4; ++i)
                b[at + i] = static_cast<unsigned char>(nan >> (8 * i));
        };
    };
    // Tile 1 (k = 2) starts after tile 0's 16 coefficients; its coefficient 5:
    const std::size_t tile1coef5 = 39 + 4 * (Tile::totalTexels(1) + 5);
    REQUIRE_THROWS_WITH(loadEdited(nanAt(tile1coef5), true),
                        Catch::Contains("tile 1: coefficient 5 is not finite"));
    REQUIRE_THROWS_AS(loadEdited(nanAt(tile1coef5), true), FileError);
}

TEST_CASE("tile file: invalid tile sets are not saved", "[tile_file]") {
    TempDir dir;
    const std::string path = dir.file("tiles.dmt");
    const TileSet good = randomTiles({2, 3}, MipFilter::Haar, 99, 11);
    dispmap::saveTiles(good, path);
    const std::vector<unsigned char> before = readBytes(path);

    const auto saveEdited = [&](const auto& edit) {
        TileSet t = good;
        edit(t);
        dispmap::saveTiles(t, path);
    };
    const auto setK = [](int k) {
        return [k](TileSet& t) {
            t.tiles[1].k = k;
            t.tiles[1].sizeDifferences = {};
            if (k >= 1) t.tiles[1].coefficients.assign(Tile::totalTexels(k), 0.5f);
        };
    };
    REQUIRE_THROWS_AS(saveEdited(setK(0)), ArgumentError);
    REQUIRE_THROWS_WITH(saveEdited(setK(0)), Catch::Contains("tile 1: k = 0 is outside [1, 8]"));
    REQUIRE_THROWS_AS(saveEdited(setK(9)), ArgumentError);
    REQUIRE_THROWS_WITH(saveEdited(setK(9)), Catch::Contains("tile 1: k = 9"));
    REQUIRE_THROWS_AS(saveEdited([](TileSet& t) { t.tiles[0].coefficients[7] = std::nanf(""); }),
                      ArgumentError);
    REQUIRE_THROWS_WITH(saveEdited([](TileSet& t) { t.tiles[0].coefficients[7] = std::nanf(""); }),
                        Catch::Contains("tile 0: coefficient 7 is not finite"));
    REQUIRE_THROWS_WITH(
        saveEdited([](TileSet& t) { t.tiles[1].coefficients[0] = -std::numeric_limits<float>::infinity(); }),
        Catch::Contains("tile 1: coefficient 0 is not finite"));
    REQUIRE_THROWS_WITH(saveEdited([](TileSet& t) { t.tiles[0].coefficients.pop_back(); }),
                        Catch::Contains("tile 0: 51 coefficients, k = 2 needs 52"));
    REQUIRE_THROWS_WITH(saveEdited([](TileSet& t) { t.tiles[0].sizeDifferences[2] = 2; }),
                        Catch::Contains("tile 0: size difference 2 at corner 2"));
    REQUIRE_THROWS_AS(saveEdited([](TileSet& t) { t.tiles[0].sizeDifferences[2] = 2; }), ArgumentError);

    // None of the failed saves touched the file or left a temporary behind.
    REQUIRE(readBytes(path) == before);
    REQUIRE(dir.entries() == std::set<std::string>{"tiles.dmt"});
}

TEST_CASE("tile file: a failed write leaves nothing half-written", "[tile_file]") {
    TempDir dir;
    const TileSet tiles = randomTiles({1, 2}, MipFilter::Haar, 5, 13);

    SECTION("into a directory that does not exist") {
        const std::string path = (dir.path / "no_such_dir" / "tiles.dmt").string();
        REQUIRE_THROWS_AS(dispmap::saveTiles(tiles, path), FileError);
        REQUIRE_THROWS_WITH(dispmap::saveTiles(tiles, path), Catch::Contains("no_such_dir"));
        REQUIRE(dir.entries().empty());
    }
    SECTION("over an existing non-empty directory (the final rename fails)") {
        const std::string path = dir.file("occupied");
        fs::create_directory(path);
        writeBytes(dir.file("occupied/keep.txt"), {'k', 'e', 'e', 'p'});
        REQUIRE_THROWS_AS(dispmap::saveTiles(tiles, path), FileError);
        REQUIRE(dir.entries() == std::set<std::string>{"occupied"}); // temporary removed
        REQUIRE(readBytes(dir.file("occupied/keep.txt")) == std::vector<unsigned char>{'k', 'e', 'e', 'p'});
    }
}

} // namespace dmtest_tile_file
