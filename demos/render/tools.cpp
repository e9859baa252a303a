// Subprocesses without a shell (posix_spawnp: no quoting of file names needed).
#include "render/tools.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

extern char** environ;

namespace tearables::render {

std::string findOnPath(const std::string& program) {
    if (program.find('/') != std::string::npos) return access(program.c_str(), X_OK) == 0 ? program : "";
    const char* path = std::getenv("PATH");
    std::stringstream dirs(path ? path : "/usr/local/bin:/usr/bin:/bin");
    std::string dir;
    while (std::getline(dirs, dir, ':')) {
        if (dir.empty()) dir = ".";
        const std::string candidate = dir + "/" + program;
        struct stat st {};
        if (stat(candidate.c_str(), &st) == 0 && S_ISREG(st.st_mode) && access(candidate.c_str(), X_OK) == 0) return candidate;
    }
    return "";
}

int runProgram(const std::vector<std::string>& argv, const std::string& log_path) {
    if (argv.empty()) return -1;
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    pid_t pid = 0;
    const int spawned = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (spawned != 0) return -1;
    int status = 0;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR) return -1;
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
    return -1;
}

std::string tailOf(const std::string& path, std::size_t max_chars) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return "";
    std::stringstream s;
    s << in.rdbuf();
    std::string text = s.str();
    if (text.size() > max_chars) text = "..." + text.substr(text.size() - max_chars);
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
    return text;
}

std::string notInstalledMessage(const std::string& program, const std::string& package, const std::string& purpose) {
    return program + " is not installed (or not on PATH); it is needed " + purpose +
           ". Install it with: sudo apt-get install " + package;
}

void makeVideo(const std::string& dir, double fps, const std::string& output) {
    if (findOnPath("ffmpeg").empty()) throw std::runtime_error(notInstalledMessage("ffmpeg", "ffmpeg", "for --mp4"));
    char rate[32];
    std::snprintf(rate, sizeof rate, "%.6g", fps);
    const std::string log = dir + "/ffmpeg.log";
    const int status = runProgram({"ffmpeg", "-y", "-loglevel", "error", "-framerate", rate, "-i", dir + "/frame_%05d.png",
                                   "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264", "-pix_fmt", "yuv420p",
                                   "-movflags", "+faststart", output},
                                  log);
    if (status != 0)
        throw std::runtime_error("ffmpeg failed (exit status " + std::to_string(status) + ") making " + output + ": " +
                                 tailOf(log) + " (full log: " + log + ")");
}

}  // namespace tearables::render
