// External programs the command line drives: ffmpeg (videos) and gnuplot (plots). Neither
// is linked; both are run as subprocesses when they are on PATH.
#pragma once

#include <string>
#include <vector>

namespace tearables::render {

/// The full path of an executable `program` found on PATH, or "" when there is none.
std::string findOnPath(const std::string& program);

/// Runs argv[0] (looked up on PATH) with the arguments, stdin from /dev/null and stdout and
/// stderr into `log_path`; returns its exit status (128 + signal when killed, -1 when it could
/// not be started).
int runProgram(const std::vector<std::string>& argv, const std::string& log_path);

/// The last `max_chars` characters of a text file (for error messages), "" when unreadable.
std::string tailOf(const std::string& path, std::size_t max_chars = 600);

/// The message for a tool that is not installed: what it is needed for and how to install it.
std::string notInstalledMessage(const std::string& program, const std::string& package, const std::string& purpose);

/// Assembles `dir`/frame_00000.png, frame_00001.png, ... into the H.264 video `output` at
/// `fps` frames per second with ffmpeg (dimensions padded to even numbers, yuv420p so that
/// every player reads it). Throws std::runtime_error when ffmpeg is missing or fails.
void makeVideo(const std::string& dir, double fps, const std::string& output);

}  // namespace tearables::render
