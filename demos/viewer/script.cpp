// Parsing of the viewer's scripts.
#include "viewer/script.hpp"

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

namespace tearables::viewer {

namespace {

/// The keys a script may press: the viewer's keyboard controls.
const std::set<std::string> kKeys = {"t", "space", "n", "r", "s", "c", "g", "f", "h", "p", "w", "b", "plus", "minus", "escape", "q", "left", "right", "backspace"};

double number(std::istringstream& in, const std::string& where, const std::string& what) {
    std::string word;
    if (!(in >> word)) throw InvalidInput(where, "expected " + what);
    std::size_t used = 0;
    double v = 0.0;
    try {
        v = std::stod(word, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used != word.size() || !std::isfinite(v)) throw InvalidInput(where, "expected " + what + ", got \"" + word + "\"");
    return v;
}

long long count(std::istringstream& in, const std::string& where) {
    const double v = number(in, where, "a count");
    if (v < 0 || v > 1e7 || v != std::floor(v)) throw InvalidInput(where, "the count must be a whole number in [0, 10000000]");
    return static_cast<long long>(v);
}

}  // namespace

std::vector<ScriptCommand> parseScript(const std::string& text) {
    std::vector<ScriptCommand> out;
    std::istringstream lines(text);
    std::string line;
    int number_of_line = 0;
    while (std::getline(lines, line)) {
        ++number_of_line;
        if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
        std::istringstream in(line);
        std::string verb;
        if (!(in >> verb)) continue;
        const std::string where = "script:" + std::to_string(number_of_line);
        ScriptCommand c;
        c.line = number_of_line;
        if (verb == "frames") {
            c.kind = ScriptCommand::Kind::Frames;
            c.count = count(in, where);
        } else if (verb == "step") {
            c.kind = ScriptCommand::Kind::Step;
            c.count = count(in, where);
        } else if (verb == "move") {
            c.kind = ScriptCommand::Kind::Move;
            c.x = number(in, where, "x in pixels");
            c.y = number(in, where, "y in pixels");
        } else if (verb == "move-world") {
            c.kind = ScriptCommand::Kind::MoveWorld;
            for (int k = 0; k < 3; ++k) c.point[k] = number(in, where, "a world point x y z in metres");
        } else if (verb == "press" || verb == "release") {
            c.kind = verb == "press" ? ScriptCommand::Kind::Press : ScriptCommand::Kind::Release;
            std::string b = "left";
            in >> b;
            if (b != "left" && b != "right") throw InvalidInput(where, "the button must be left or right, got \"" + b + "\"");
            c.button = b == "left" ? 0 : 1;
        } else if (verb == "key") {
            c.kind = ScriptCommand::Kind::Key;
            if (!(in >> c.key) || !kKeys.count(c.key)) {
                std::string known;
                for (const std::string& k : kKeys) known += " " + k;
                throw InvalidInput(where, "unknown key \"" + c.key + "\" (known:" + known + ")");
            }
        } else if (verb == "screenshot") {
            c.kind = ScriptCommand::Kind::Screenshot;
            if (!(in >> c.path)) throw InvalidInput(where, "expected a file name");
        } else if (verb == "quit") {
            c.kind = ScriptCommand::Kind::Quit;
        } else {
            throw InvalidInput(where, "unknown command \"" + verb +
                                          "\" (frames, step, move, move-world, press, release, key, screenshot, quit)");
        }
        std::string extra;
        if (in >> extra) throw InvalidInput(where, "unexpected \"" + extra + "\" after the command");
        out.push_back(c);
    }
    return out;
}

std::vector<ScriptCommand> loadScript(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error("cannot read the script " + path);
    std::stringstream text;
    text << in.rdbuf();
    return parseScript(text.str());
}

}  // namespace tearables::viewer
