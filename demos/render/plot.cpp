// Plots of a run: the trace is reduced to one row per frame and string, gnuplot draws them.
//
// Per string and frame (segments that are broken are left out):
//   tension  = the largest segment tension, N;
//   length   = the sum of the intact segments' lengths, m;
//   gamma    = the largest torsional strain over joints, r (theta_{k+1} - theta_k) / l with l
//              the mean rest length of the two segments (as src/string/fracture.cpp);
//   strain, stress = of the most loaded segment: its length over its length at frame 0,
//              minus 1, and its tension over the original section pi r^2 (engineering
//              stress, as the core's material curve is written).
// The material curve beside the points is the bilinear one of Strings, Sec. 5.1: slope E up
// to the yield stress, the plastic slope up to rupture. The torsion panel is drawn only when
// some string twists (gamma > 0 in some frame): an all-zero panel says nothing.
//
// Per cloth and frame: the largest yarn tension, N, and the number of torn yarns (the trace's
// "broken" list). Per paper sheet and frame: its crease and tear counters and its broken
// structural springs (the trace's "creases", "tears", "broken_springs").
#include "render/plot.hpp"

#include "render/tools.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>

namespace tearables::render {

namespace {

using json = nlohmann::json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A gnuplot string literal (single quotes; a quote is doubled).
std::string gpQuoted(const std::string& s) {
    std::string out = "'";
    for (char c : s) {
        if (c == '\'') out += "''";
        else out += c;
    }
    return out + "'";
}

/// Text for gnuplot's enhanced mode: its control characters escaped.
std::string label(const std::string& s) {
    std::string out;
    for (char c : s) {
        if (c == '_' || c == '^' || c == '{' || c == '}' || c == '@' || c == '&' || c == '~') out += "\\\\";
        out += c;
    }
    return out;
}

std::string number(double v) {
    if (!std::isfinite(v)) return "NaN";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return buf;
}

Vec3 point(const json& p) { return {p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()}; }

}  // namespace

void checkPlottable(const scene::Scene& scene) {
    if (scene.strings.empty() && scene.cloths.empty() && scene.papers.empty())
        throw InvalidInput("--plot", "plots strings, cloths and paper sheets, and the scene has none");
}

void writePlots(const scene::Scene& scene, const std::string& dir, int width, int height) {
    if (findOnPath("gnuplot").empty())
        throw std::runtime_error(notInstalledMessage("gnuplot", "gnuplot-nox", "for --plot"));
    checkPlottable(scene);

    const std::string trace_path = dir + "/trace.jsonl";
    std::ifstream trace(trace_path);
    if (!trace) throw std::runtime_error("--plot: cannot read " + trace_path);

    // One data file per string, cloth and paper sheet.
    const std::size_t n = scene.strings.size(), nc = scene.cloths.size(), np = scene.papers.size();
    std::vector<std::ofstream> data(n + nc + np);
    std::vector<std::string> data_paths(n + nc + np);
    const auto open = [&](std::size_t k, const std::string& stem, const std::string& header) {
        data_paths[k] = dir + "/" + stem + ".dat";
        data[k].open(data_paths[k]);
        if (!data[k]) throw std::runtime_error("--plot: cannot write " + data_paths[k]);
        data[k] << header;
    };
    for (std::size_t i = 0; i < n; ++i)
        open(i, "plot_" + std::to_string(i),
             "# " + scene.strings[i].desc.name + "\n# t[s] tension[N] length[m] gamma strain stress[MPa]\n");
    for (std::size_t i = 0; i < nc; ++i)
        open(n + i, "plot_cloth_" + std::to_string(i), "# " + scene.cloths[i].desc.name + "\n# t[s] tension[N] torn_yarns\n");
    for (std::size_t i = 0; i < np; ++i)
        open(n + nc + i, "plot_paper_" + std::to_string(i),
             "# " + scene.papers[i].desc.name + "\n# t[s] creases tears broken_springs\n");
    double most_gamma = 0.0;  // the largest torsional strain of any string in any frame
    std::vector<std::vector<double>> length0(n);  // per string, per segment: length at frame 0
    std::string line;
    std::size_t frames = 0;
    while (std::getline(trace, line)) {
        if (line.empty()) continue;
        json f;
        try {
            f = json::parse(line);
        } catch (const json::exception& e) {
            throw std::runtime_error("--plot: " + trace_path + " line " + std::to_string(frames + 1) + ": " + e.what());
        }
        const double t = f.at("t").get<double>();
        const json none = json::object();
        const json& strings = f.contains("strings") ? f.at("strings") : none;
        for (std::size_t i = 0; i < n; ++i) {
            const scene::String& spec = scene.strings[i];
            const auto it = strings.find(spec.desc.name);
            if (it == strings.end()) continue;
            const json& s = *it;
            const json& x = s.at("x");
            const json& tension = s.at("tension");
            const json& twist = s.at("twist");
            const json& rest = s.at("rest_length");
            const std::size_t m = tension.size();
            std::vector<double> len(m, kNaN);
            for (std::size_t j = 0; j < m && j + 1 < x.size(); ++j) len[j] = (point(x[j + 1]) - point(x[j])).norm();
            if (length0[i].empty()) length0[i] = len;
            const double r = spec.desc.radius;
            const double area = M_PI * r * r;
            double max_tension = kNaN, total = 0.0, gamma = kNaN, strain = kNaN, stress = kNaN;
            for (std::size_t j = 0; j < m; ++j) {
                if (tension[j].is_null()) continue;  // broken
                total += len[j];
                const double tj = tension[j].get<double>();
                if (!(tj <= max_tension)) {
                    max_tension = tj;
                    strain = len[j] / length0[i][j] - 1.0;
                    stress = tj / area * 1e-6;
                }
                if (j + 1 < m && !tension[j + 1].is_null()) {
                    const double l = 0.5 * (rest[j].get<double>() + rest[j + 1].get<double>());
                    const double g = std::abs(r * (twist[j + 1].get<double>() - twist[j].get<double>()) / l);
                    if (!(g <= gamma)) gamma = g;
                }
            }
            if (gamma > most_gamma) most_gamma = gamma;
            data[i] << number(t) << ' ' << number(max_tension) << ' ' << number(total) << ' ' << number(gamma) << ' '
                    << number(strain) << ' ' << number(stress) << '\n';
        }
        const json& cloths = f.contains("cloths") ? f.at("cloths") : none;
        for (std::size_t i = 0; i < nc; ++i) {
            const auto it = cloths.find(scene.cloths[i].desc.name);
            if (it == cloths.end()) continue;
            double max_tension = kNaN;
            for (const json& tj : it->at("tension"))
                if (!tj.is_null() && !(tj.get<double>() <= max_tension)) max_tension = tj.get<double>();
            data[n + i] << number(t) << ' ' << number(max_tension) << ' ' << it->at("broken").size() << '\n';
        }
        const json& papers = f.contains("papers") ? f.at("papers") : none;
        for (std::size_t i = 0; i < np; ++i) {
            const auto it = papers.find(scene.papers[i].desc.name);
            if (it == papers.end()) continue;
            data[n + nc + i] << number(t) << ' ' << it->value("creases", 0LL) << ' ' << it->value("tears", 0LL) << ' '
                             << it->value("broken_springs", 0LL) << '\n';
        }
        ++frames;
    }
    if (frames == 0) throw std::runtime_error("--plot: " + trace_path + " holds no frames");
    for (auto& d : data) {
        d.close();
        if (!d) throw std::runtime_error("--plot: writing the plot data in " + dir + " failed");
    }

    // The material curves: (0, 0), (yield strain, yield), (rupture strain, rupture).
    const std::string curves_path = dir + "/plot_material.dat";
    if (n > 0) {
        std::ofstream curves(curves_path);
        for (std::size_t i = 0; i < n; ++i) {
            const TensileCurve& c = scene.strings[i].desc.material.tensile;
            const double eps_y = c.yield / c.young;
            const double eps_r = eps_y + (c.rupture - c.yield) / c.plastic_modulus;
            curves << "# " << scene.strings[i].desc.name << "\n0 0\n" << number(eps_y) << ' ' << number(c.yield * 1e-6) << '\n'
                   << number(eps_r) << ' ' << number(c.rupture * 1e-6) << "\n\n\n";
        }
        if (!curves) throw std::runtime_error("--plot: cannot write " + curves_path);
    }

    // The panels, each a gnuplot block (title, labels, plot command).
    std::vector<std::string> panels;
    const auto series = [&](std::size_t first, std::size_t count, const std::string& using_cols, const std::string& style,
                            const auto& name) {
        std::string cmd = "plot ";
        for (std::size_t i = 0; i < count; ++i) {
            if (i) cmd += ", \\\n     ";
            cmd += gpQuoted(data_paths[first + i]) + " using " + using_cols + " with " + style + " lt " +
                   std::to_string(i + 1) + " title " + gpQuoted(label(name(i)));
        }
        return cmd + "\n";
    };
    const auto stringName = [&](std::size_t i) { return scene.strings[i].desc.name; };
    const auto clothName = [&](std::size_t i) { return scene.cloths[i].desc.name; };
    const auto paperName = [&](std::size_t i) { return scene.papers[i].desc.name; };
    const std::string time_axis = "set xlabel 't [s]'\nset autoscale x\n";
    if (n > 0) {
        panels.push_back("set title 'Tension (most loaded segment)'\n" + time_axis + "set ylabel 'T [N]'\n" +
                         series(0, n, "1:2", "lines lw 2", stringName));
        panels.push_back("set title 'Length (intact segments)'\n" + time_axis + "set ylabel 'L [m]'\n" +
                         series(0, n, "1:3", "lines lw 2", stringName));
        std::string cmd = "plot ";
        for (std::size_t i = 0; i < n; ++i) {
            if (i) cmd += ", \\\n     ";
            cmd += gpQuoted(curves_path) + " index " + std::to_string(i) + " using 1:2 with lines lw 2 dt 2 lt " +
                   std::to_string(i + 1) + " notitle, \\\n     " + gpQuoted(data_paths[i]) +
                   " using 5:6 with points pt 7 ps 0.5 lt " + std::to_string(i + 1) + " title " +
                   gpQuoted(label(scene.strings[i].desc.name));
        }
        panels.push_back("set title 'Stress-strain (dashed: material curve)'\n"
                         "set xlabel 'strain of the most loaded segment'\nset ylabel 'stress [MPa]'\n" +
                         cmd + "\n");
        if (most_gamma > 0.0) {
            cmd = "plot ";
            for (std::size_t i = 0; i < n; ++i) {
                if (i) cmd += ", \\\n     ";
                cmd += gpQuoted(data_paths[i]) + " using 1:4 with lines lw 2 lt " + std::to_string(i + 1) + " title " +
                       gpQuoted(label(scene.strings[i].desc.name)) + ", \\\n     " +
                       number(scene.strings[i].desc.material.torsion.rupture) + " with lines dt 2 lt " +
                       std::to_string(i + 1) + " notitle";
            }
            panels.push_back("set title 'Torsional strain (dashed: rupture)'\n" + time_axis +
                             "set ylabel '{/Symbol g} = r d{/Symbol q}/ds'\n" + cmd + "\n");
        }
    }
    if (nc > 0) {
        panels.push_back("set title 'Cloth: tension (most loaded yarn)'\n" + time_axis + "set ylabel 'T [N]'\n" +
                         series(n, nc, "1:2", "lines lw 2", clothName));
        panels.push_back("set title 'Cloth: torn yarns'\n" + time_axis + "set ylabel 'yarns'\n" +
                         series(n, nc, "1:3", "steps lw 2", clothName));
    }
    if (np > 0) {
        std::string cmd = series(n + nc, np, "1:2", "steps lw 2", paperName);
        cmd.pop_back();  // the tears join the creases' plot command (a second command is a new panel)
        for (std::size_t i = 0; i < np; ++i)
            cmd += ", \\\n     " + gpQuoted(data_paths[n + nc + i]) + " using 1:3 with steps lw 2 dt 2 lt " +
                   std::to_string(i + 1) + " notitle";
        panels.push_back("set title 'Paper: creases (solid) and tears (dashed)'\n" + time_axis + "set ylabel 'count'\n" +
                         cmd + "\n");
        panels.push_back("set title 'Paper: broken springs'\n" + time_axis + "set ylabel 'springs'\n" +
                         series(n + nc, np, "1:4", "steps lw 2", paperName));
    }

    const std::string png_path = dir + "/plot.png";
    const std::string script_path = dir + "/plot.gp";
    {
        std::ofstream gp(script_path);
        gp << "# Generated by `tearables run ... --plot`: gnuplot " << gpQuoted(script_path) << " redraws plot.png\n";
        gp << "set terminal pngcairo size " << width << "," << height << " enhanced font 'DejaVu Sans,10'\n";
        gp << "set output " << gpQuoted(png_path) << "\n";
        gp << "set datafile missing 'NaN'\nset key top left box opaque font ',9'\nset grid\n";
        const std::size_t cols = panels.size() == 1 ? 1 : 2, rows = (panels.size() + cols - 1) / cols;
        gp << "set multiplot layout " << rows << "," << cols << " title "
           << gpQuoted(label(scene.source.empty() ? "scene" : scene.source)) << "\n";
        for (const std::string& panel : panels) gp << panel;
        gp << "unset multiplot\n";
        if (!gp) throw std::runtime_error("--plot: cannot write " + script_path);
    }
    const std::string log = dir + "/plot.log";
    const int status = runProgram({"gnuplot", script_path}, log);
    if (status != 0)
        throw std::runtime_error("gnuplot failed (exit status " + std::to_string(status) + "): " + tailOf(log) +
                                 " (script: " + script_path + ")");
}

}  // namespace tearables::render
