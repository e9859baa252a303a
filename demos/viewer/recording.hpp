// A recorded run for playback (`tearables view SCENE --trace OUT_DIR`): the frames of
// OUT_DIR/trace.jsonl and the events of OUT_DIR/events.jsonl, as `tearables run --out`
// writes them (docs/SCENE_FORMAT.md, "Output"), turned back into FrameStates to draw.
#pragma once

#include "tearables/scene.hpp"

#include <string>
#include <vector>

namespace tearables::viewer {

/// One string of one recorded frame (what the trace holds; the rest is empty).
struct RecordedString {
    std::vector<Vec3> x;
    std::vector<double> tension, twist, rest_length;
    std::vector<std::uint8_t> broken;
};

struct RecordedFrame {
    long long step = 0;
    double time = 0.0;
    std::vector<RecordedString> strings;       ///< by the scene's string index
    std::vector<scene::FrameBody> bodies;      ///< those the frame names, with the scene's shapes
    std::vector<std::vector<Vec3>> paper_x;    ///< by the scene's paper index
    std::vector<std::vector<std::array<std::uint32_t, 3>>> paper_triangles;
};

/// A recorded event: its time and a line to show.
struct RecordedEvent {
    double time = 0.0;
    std::string text;
};

class Recording {
public:
    /// Reads DIR/trace.jsonl (required) and DIR/events.jsonl (optional) of a run of `scene`.
    /// Throws InvalidInput("--trace") when the files are missing, unreadable or do not
    /// match the scene (a string or body the scene does not have, a wrong particle count).
    Recording(const scene::Scene& scene, const std::string& dir);

    std::size_t size() const { return frames_.size(); }
    const RecordedFrame& at(std::size_t i) const { return frames_[i]; }
    /// The frame shown at time t: the last at or before t (the first before it starts).
    std::size_t frameAt(double t) const;
    double startTime() const { return frames_.front().time; }
    double endTime() const { return frames_.back().time; }
    /// The frame as the painter wants it (views into the recording: valid while it lives).
    scene::FrameState state(std::size_t i) const;
    const std::vector<RecordedEvent>& events() const { return events_; }

private:
    const scene::Scene& scene_;
    std::vector<RecordedFrame> frames_;
    std::vector<RecordedEvent> events_;
    std::vector<std::vector<double>> masses_;  // per string: ones (the views want a pointer)
    std::vector<std::vector<Vec3>> zeros_;     // per string: zero velocities
};

}  // namespace tearables::viewer
