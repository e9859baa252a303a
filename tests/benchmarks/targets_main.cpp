// tearables_bench_targets: issue 9's targets from saved runs of the benchmark suite.
//
//   for r in 1 2 3; do ./build/tests/benchmarks/tearables_bench --benchmark_out=run$r.json --benchmark_out_format=json; done
//   ./build/tests/benchmarks/tearables_bench_targets run1.json run2.json run3.json
//
// Prints a Markdown table: each target with the fastest and the median of the runs and
// whether it is met (targets.hpp). Exit status 0; 1 with --strict where a target is not
// met by the median (or missing from the runs); 2 for unreadable input.
#include "targets.hpp"

#include <cstdio>
#include <fstream>
#include <string>

int main(int argc, char** argv) {
    bool strict = false;
    std::vector<std::string> files;
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        if (arg == "--strict")
            strict = true;
        else if (arg == "-h" || arg == "--help") {
            std::printf("usage: %s [--strict] RUN.json...\n(RUN.json: tearables_bench --benchmark_out=RUN.json --benchmark_out_format=json)\n",
                        argv[0]);
            return 0;
        } else
            files.push_back(arg);
    }
    if (files.empty()) {
        std::fprintf(stderr, "%s: no runs given (usage: %s [--strict] RUN.json...)\n", argv[0], argv[0]);
        return 2;
    }
    tearables::bench::Runs runs;
    for (const std::string& file : files) {
        std::ifstream in(file);
        if (!in) {
            std::fprintf(stderr, "%s: cannot open %s\n", argv[0], file.c_str());
            return 2;
        }
        try {
            tearables::bench::addRun(runs, nlohmann::json::parse(in));
        } catch (const std::exception& e) {
            std::fprintf(stderr, "%s: %s: %s\n", argv[0], file.c_str(), e.what());
            return 2;
        }
    }
    const auto rows = tearables::bench::judge(runs);
    std::printf("%zu run(s), %zu benchmarks\n\n%s", files.size(), runs.size(), tearables::bench::markdown(rows).c_str());
    if (strict)
        for (const auto& r : rows)
            if (r.verdict != tearables::bench::Verdict::Met) return 1;
    return 0;
}
