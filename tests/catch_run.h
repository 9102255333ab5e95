#pragma once
// Catch2's session for the test mains. Catch2 v2 declares Catch::Session only in the translation
// unit that holds its implementation (tests/catch_impl.cpp, compiled once for both test
// executables), so the mains call it through this function.
#include <functional>

namespace dmtest {
/// Parses the command line and runs the tests. `before` (optional) runs after parsing, with
/// true when Catch will only list tests or show help; a non-zero result ends the run with it.
int runCatch(int argc, char* argv[], const std::function<int(bool listing)>& before = {});
} // namespace dmtest
