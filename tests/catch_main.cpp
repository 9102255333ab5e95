// The main of the CPU tests (Catch2's implementation is catch_impl.cpp).
#include "catch_run.h"

int main(int argc, char* argv[]) { return dmtest::runCatch(argc, argv); }
