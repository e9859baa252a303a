// Plots of a run with gnuplot (run as a subprocess on a generated script): for each string,
// tension and length over time, torsional strain over time, and the material's stress-strain
// curve with the simulated points on it (Strings, Fig. 7-9).
#pragma once

#include "tearables/scene.hpp"

#include <string>

namespace tearables::render {

/// Reads `dir`/trace.jsonl (written by runScene) and writes `dir`/plot.png (width x height
/// pixels), with the data (`plot_<i>.dat`, one per string) and the script (`plot.gp`) beside
/// it. Throws std::runtime_error when gnuplot is missing (saying how to install it), the trace
/// cannot be read, or gnuplot fails.
void writePlots(const scene::Scene& scene, const std::string& dir, int width = 1200, int height = 900);

}  // namespace tearables::render
