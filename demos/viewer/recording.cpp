// Reading a recorded run back (trace.jsonl, events.jsonl) for playback.
#include "viewer/recording.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

namespace tearables::viewer {

namespace {

using json = nlohmann::json;

Vec3 vec3(const json& j, const std::string& where) {
    if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number())
        throw InvalidInput("--trace", where + ": expected [x, y, z]");
    return Vec3(j[0].get<double>(), j[1].get<double>(), j[2].get<double>());
}

}  // namespace

Recording::Recording(const scene::Scene& scene, const std::string& dir) : scene_(scene) {
    const std::filesystem::path trace_path = std::filesystem::path(dir) / "trace.jsonl";
    std::ifstream trace(trace_path);
    if (!trace) throw InvalidInput("--trace", "no " + trace_path.string() + " (write one with `tearables run SCENE --out DIR`)");

    std::map<std::string, std::size_t> string_index, paper_index;
    for (std::size_t i = 0; i < scene.strings.size(); ++i) string_index[scene.strings[i].desc.name] = i;
    for (std::size_t i = 0; i < scene.papers.size(); ++i) paper_index[scene.papers[i].desc.name] = i;
    std::map<std::string, scene::Shape> shapes;
    for (const scene::Body& b : scene.bodies) shapes[b.name] = b.shape;
    for (const scene::Driver& d : scene.drivers)
        if (d.body) shapes[d.body->name] = d.body->shape;

    std::string line;
    int number = 0;
    while (std::getline(trace, line)) {
        ++number;
        if (line.empty()) continue;
        const std::string where = trace_path.filename().string() + ":" + std::to_string(number);
        const json f = json::parse(line, nullptr, false);
        if (!f.is_object() || !f.contains("step") || !f.contains("t")) throw InvalidInput("--trace", where + ": not a trace frame");
        RecordedFrame frame;
        frame.step = f["step"].get<long long>();
        frame.time = f["t"].get<double>();
        frame.strings.resize(scene.strings.size());
        if (f.contains("strings"))
            for (const auto& [name, s] : f["strings"].items()) {
                const auto it = string_index.find(name);
                if (it == string_index.end()) throw InvalidInput("--trace", where + ": string \"" + name + "\" is not in the scene");
                RecordedString& r = frame.strings[it->second];
                for (const json& p : s.at("x")) r.x.push_back(vec3(p, where));
                if (r.x.size() != scene.strings[it->second].desc.points.size())
                    throw InvalidInput("--trace", where + ": string \"" + name + "\" has " + std::to_string(r.x.size()) +
                                                      " particles, the scene's " +
                                                      std::to_string(scene.strings[it->second].desc.points.size()));
                const std::size_t segments = r.x.size() - 1;
                r.tension.assign(segments, 0.0);
                r.twist.assign(segments, 0.0);
                r.rest_length.assign(segments, 0.0);
                r.broken.assign(segments, 0);
                const json& tension = s.at("tension");
                for (std::size_t j = 0; j < segments && j < tension.size(); ++j)
                    r.tension[j] = tension[j].is_number() ? tension[j].get<double>() : 0.0;
                if (s.contains("twist"))
                    for (std::size_t j = 0; j < segments && j < s["twist"].size(); ++j) r.twist[j] = s["twist"][j].get<double>();
                if (s.contains("rest_length"))
                    for (std::size_t j = 0; j < segments && j < s["rest_length"].size(); ++j)
                        r.rest_length[j] = s["rest_length"][j].get<double>();
                for (const json& b : s.at("broken")) {
                    const auto j = b.get<std::size_t>();
                    if (j < segments) r.broken[j] = 1;
                }
            }
        frame.paper_x.resize(scene.papers.size());
        frame.paper_triangles.resize(scene.papers.size());
        if (f.contains("papers"))
            for (const auto& [name, p] : f["papers"].items()) {
                const auto it = paper_index.find(name);
                if (it == paper_index.end()) throw InvalidInput("--trace", where + ": paper \"" + name + "\" is not in the scene");
                for (const json& x : p.at("x")) frame.paper_x[it->second].push_back(vec3(x, where));
                for (const json& t : p.at("triangles"))
                    frame.paper_triangles[it->second].push_back({t[0].get<std::uint32_t>(), t[1].get<std::uint32_t>(), t[2].get<std::uint32_t>()});
            }
        if (f.contains("bodies"))
            for (const auto& [name, b] : f["bodies"].items()) {
                const auto it = shapes.find(name);
                if (it == shapes.end()) throw InvalidInput("--trace", where + ": body \"" + name + "\" is not in the scene");
                scene::FrameBody body;
                body.name = name;
                body.shape = it->second;
                body.position = vec3(b.at("p"), where);
                const json& q = b.at("q");
                body.orientation = Quat(q[3].get<double>(), q[0].get<double>(), q[1].get<double>(), q[2].get<double>());
                frame.bodies.push_back(body);
            }
        if (!frames_.empty() && frame.time < frames_.back().time)
            throw InvalidInput("--trace", where + ": frames must come in time order");
        frames_.push_back(std::move(frame));
    }
    if (frames_.empty()) throw InvalidInput("--trace", trace_path.string() + " holds no frame");

    masses_.resize(scene.strings.size());
    zeros_.resize(scene.strings.size());
    for (std::size_t i = 0; i < scene.strings.size(); ++i) {
        masses_[i].assign(scene.strings[i].desc.points.size(), 0.0);
        zeros_[i].assign(scene.strings[i].desc.points.size(), Vec3::Zero());
    }

    std::ifstream events(std::filesystem::path(dir) / "events.jsonl");
    while (events && std::getline(events, line)) {
        const json e = json::parse(line, nullptr, false);
        if (!e.is_object() || !e.contains("t") || !e.contains("type")) continue;
        std::string text = e["type"].get<std::string>();
        if (e.contains("object")) text += " " + e["object"].get<std::string>();
        if (e.contains("segment")) text += " [" + std::to_string(e["segment"].get<long long>()) + "]";
        if (e.contains("cause")) text += " (" + e["cause"].get<std::string>() + ")";
        events_.push_back({e["t"].get<double>(), text});
    }
}

std::size_t Recording::frameAt(double t) const {
    const auto it = std::upper_bound(frames_.begin(), frames_.end(), t, [](double v, const RecordedFrame& f) { return v < f.time; });
    return it == frames_.begin() ? 0 : static_cast<std::size_t>(it - frames_.begin() - 1);
}

scene::FrameState Recording::state(std::size_t i) const {
    const RecordedFrame& f = frames_.at(i);
    scene::FrameState s;
    s.step = f.step;
    s.time = f.time;
    for (std::size_t k = 0; k < f.strings.size(); ++k) {
        const RecordedString& r = f.strings[k];
        if (r.x.empty()) continue;  // not in this frame
        StringView v;
        v.positions = &r.x;
        v.velocities = &zeros_[k];
        v.masses = &masses_[k];
        v.tension = &r.tension;
        v.twist = &r.twist;
        v.rest_length = &r.rest_length;
        v.max_length = &r.rest_length;
        v.broken = &r.broken;
        v.radius = scene_.strings[k].desc.radius;
        s.strings.push_back({scene_.strings[k].desc.name, v, scene_.strings[k].desc.material.tensile.rupture,
                             scene_.strings[k].desc.material.torsion.rupture});
    }
    for (std::size_t k = 0; k < f.paper_x.size(); ++k) {
        if (f.paper_x[k].empty()) continue;
        scene::FramePaper p;
        p.name = scene_.papers[k].desc.name;
        p.view.positions = &f.paper_x[k];
        p.view.triangles = &f.paper_triangles[k];
        s.papers.push_back(p);
    }
    s.bodies = f.bodies;
    return s;
}

}  // namespace tearables::viewer
