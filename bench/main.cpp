// The one main() of denoisebench_bench: the other bench/*.cpp files only register cases.
#include <benchmark/benchmark.h>

BENCHMARK_MAIN();
