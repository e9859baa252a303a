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
// to the yield stress, the plastic slope up to rupture.
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

void writePlots(const scene::Scene& scene, const std::string& dir, int width, int height) {
    if (findOnPath("gnuplot").empty())
        throw std::runtime_error(notInstalledMessage("gnuplot", "gnuplot-nox", "for --plot"));
    if (scene.strings.empty()) throw std::runtime_error("--plot: the scene has no strings to plot");

    const std::string trace_path = dir + "/trace.jsonl";
    std::ifstream trace(trace_path);
    if (!trace) throw std::runtime_error("--plot: cannot read " + trace_path);

    const std::size_t n = scene.strings.size();
    std::vector<std::ofstream> data(n);
    std::vector<std::string> data_paths(n);
    for (std::size_t i = 0; i < n; ++i) {
        data_paths[i] = dir + "/plot_" + std::to_string(i) + ".dat";
        data[i].open(data_paths[i]);
        if (!data[i]) throw std::runtime_error("--plot: cannot write " + data_paths[i]);
        data[i] << "# " << scene.strings[i].desc.name << "\n# t[s] tension[N] length[m] gamma strain stress[MPa]\n";
    }
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
        for (std::size_t i = 0; i < n; ++i) {
            const scene::String& spec = scene.strings[i];
            const auto it = f.at("strings").find(spec.desc.name);
            if (it == f.at("strings").end()) continue;
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
            data[i] << number(t) << ' ' << number(max_tension) << ' ' << number(total) << ' ' << number(gamma) << ' '
                    << number(strain) << ' ' << number(stress) << '\n';
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
    {
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

    const std::string png_path = dir + "/plot.png";
    const std::string script_path = dir + "/plot.gp";
    {
        std::ofstream gp(script_path);
        gp << "# Generated by `tearables run ... --plot`: gnuplot " << gpQuoted(script_path) << " redraws plot.png\n";
        gp << "set terminal pngcairo size " << width << "," << height << " enhanced font 'DejaVu Sans,10'\n";
        gp << "set output " << gpQuoted(png_path) << "\n";
        gp << "set datafile missing 'NaN'\nset key top left box opaque font ',9'\nset grid\n";
        gp << "set multiplot layout 2,2 title " << gpQuoted(label(scene.source.empty() ? "scene" : scene.source)) << "\n";
        const auto plotAll = [&](const std::string& using_cols, const std::string& style) {
            std::string cmd = "plot ";
            for (std::size_t i = 0; i < n; ++i) {
                if (i) cmd += ", \\\n     ";
                cmd += gpQuoted(data_paths[i]) + " using " + using_cols + " with " + style + " lt " + std::to_string(i + 1) +
                       " title " + gpQuoted(label(scene.strings[i].desc.name));
            }
            return cmd + "\n";
        };
        gp << "set title 'Tension (most loaded segment)'\nset xlabel 't [s]'\nset ylabel 'T [N]'\n";
        gp << plotAll("1:2", "lines lw 2");
        gp << "set title 'Length (intact segments)'\nset ylabel 'L [m]'\n";
        gp << plotAll("1:3", "lines lw 2");
        gp << "set title 'Stress-strain (dashed: material curve)'\n"
              "set xlabel 'strain of the most loaded segment'\nset ylabel 'stress [MPa]'\n";
        {
            std::string cmd = "plot ";
            for (std::size_t i = 0; i < n; ++i) {
                if (i) cmd += ", \\\n     ";
                cmd += gpQuoted(curves_path) + " index " + std::to_string(i) + " using 1:2 with lines lw 2 dt 2 lt " +
                       std::to_string(i + 1) + " notitle, \\\n     " + gpQuoted(data_paths[i]) +
                       " using 5:6 with points pt 7 ps 0.5 lt " + std::to_string(i + 1) + " title " +
                       gpQuoted(label(scene.strings[i].desc.name));
            }
            gp << cmd << "\n";
        }
        gp << "set title 'Torsional strain (dashed: rupture)'\nset xlabel 't [s]'\nset ylabel '{/Symbol g} = r d{/Symbol q}/ds'\n";
        {
            std::string cmd = "plot ";
            for (std::size_t i = 0; i < n; ++i) {
                if (i) cmd += ", \\\n     ";
                cmd += gpQuoted(data_paths[i]) + " using 1:4 with lines lw 2 lt " + std::to_string(i + 1) + " title " +
                       gpQuoted(label(scene.strings[i].desc.name)) + ", \\\n     " +
                       number(scene.strings[i].desc.material.torsion.rupture) + " with lines dt 2 lt " +
                       std::to_string(i + 1) + " notitle";
            }
            gp << cmd << "\n";
        }
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
