// Plots of a run with gnuplot (run as a subprocess on a generated script): for each string,
// tension and length over time, torsional strain over time (when a string twists), and the
// material's stress-strain curve with the simulated points on it (Strings, Fig. 7-9); for
// each cloth, its most loaded yarn's tension and its torn yarns over time; for each paper
// sheet, its creases, tears and broken springs over time.
#pragma once

#include "tearables/scene.hpp"

#include <string>

namespace tearables::render {

/// Throws InvalidInput("--plot") when the scene has nothing to plot (no string, cloth or
/// paper sheet): called before simulating.
void checkPlottable(const scene::Scene& scene);

/// Reads `dir`/trace.jsonl (written by runScene) and writes `dir`/plot.png (width x height
/// pixels), with the data (`plot_<i>.dat` per string, `plot_cloth_<i>.dat` per cloth,
/// `plot_paper_<i>.dat` per paper sheet) and the script (`plot.gp`) beside
/// it. Throws std::runtime_error when gnuplot is missing (saying how to install it), the trace
/// cannot be read, or gnuplot fails; InvalidInput as checkPlottable.
void writePlots(const scene::Scene& scene, const std::string& dir, int width = 1200, int height = 900);

}  // namespace tearables::render
