// Catch2's implementation, compiled once for both test executables (each has its own main,
// which reaches the session through catch_run.h).
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include "catch_run.h"

int dmtest::runCatch(int argc, char* argv[], const std::function<int(bool listing)>& before) {
    Catch::Session session;
    if (const int rc = session.applyCommandLine(argc, argv); rc != 0) return rc;
    const Catch::ConfigData& config = session.configData();
    const bool listing = config.showHelp || config.listTests || config.listTestNamesOnly || config.listTags ||
                         config.listReporters;
    if (before)
        if (const int rc = before(listing); rc != 0) return rc;
    return session.run();
}
