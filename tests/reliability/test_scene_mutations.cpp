// Issue 8: the fuzzer's plain-g++ companion. Every demo scene, truncated at many points,
// with random bytes flipped, tokens swapped for hostile values and chunks deleted or
// repeated (a fixed seed: the same inputs every run), goes through parseScene, which must
// either return a scene or throw the documented tearables::InvalidInput; never anything
// else, never a crash (the sanitizer build runs this too).
#include "tearables/scene.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace {

using tearables::scene::parseScene;

std::vector<std::pair<std::string, std::string>> corpus() {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& [name, description] : tearables::scene::builtinScenes())
        out.emplace_back(name, *tearables::scene::builtinSceneText(name));
    const std::filesystem::path dir = std::filesystem::path(TEARABLES_SOURCE_DIR) / "tests/reliability/scenes";
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        std::ifstream in(entry.path());
        std::ostringstream s;
        s << in.rdbuf();
        out.emplace_back(entry.path().filename().string(), s.str());
    }
    return out;
}

/// 0: parsed, 1: refused with InvalidInput; anything else fails the test.
int attempt(const std::string& text, const std::string& label) {
    try {
        parseScene(text);
        return 0;
    } catch (const tearables::InvalidInput& e) {
        EXPECT_NE(std::string(e.what()), "") << label;
        return 1;
    } catch (const std::exception& e) {
        ADD_FAILURE() << label << ": threw " << typeid(e).name() << " (not InvalidInput): " << e.what();
    } catch (...) {
        ADD_FAILURE() << label << ": threw a non-exception";
    }
    return 2;
}

TEST(SceneMutations, EveryMutantParsesOrIsRefusedWithInvalidInput) {
    const auto scenes = corpus();
    ASSERT_GE(scenes.size(), 5u);
    const std::vector<std::string> hostile = {"1e999", "-1e999", "-1", "0", "1e308", "null", "\"\"", "[]", "{}", "true",
                                              "18446744073709551616", "-0", "1e-320", "[[[[[[[[[[]]]]]]]]]]", "\"\\u0000\""};
    std::mt19937_64 rng(20261122);
    int parsed = 0, refused = 0, inputs = 0;
    for (const auto& [name, text] : scenes) {
        // Truncations: every 1/64th of the text.
        for (std::size_t k = 0; k < 64; ++k) {
            const std::size_t keep = text.size() * k / 64;
            const int r = attempt(text.substr(0, keep), name + " truncated to " + std::to_string(keep));
            parsed += r == 0, refused += r == 1, ++inputs;
        }
        std::uniform_int_distribution<std::size_t> pos(0, text.size() - 1);
        std::uniform_int_distribution<int> byte(0, 255);
        // Random byte flips, 1 to 4 at a time.
        for (int k = 0; k < 120; ++k) {
            std::string m = text;
            const int flips = 1 + k % 4;
            for (int f = 0; f < flips; ++f) m[pos(rng)] = static_cast<char>(byte(rng));
            const int r = attempt(m, name + " flip " + std::to_string(k));
            parsed += r == 0, refused += r == 1, ++inputs;
        }
        // Every number (a digit run) in turn replaced by a hostile token, up to 60 of them.
        int replaced = 0;
        for (std::size_t i = 0; i < text.size() && replaced < 60; ++i) {
            if (!std::isdigit(static_cast<unsigned char>(text[i])) || (i > 0 && std::isalnum(static_cast<unsigned char>(text[i - 1]))))
                continue;
            std::size_t j = i;
            while (j < text.size() && (std::isdigit(static_cast<unsigned char>(text[j])) || text[j] == '.' || text[j] == 'e' ||
                                       text[j] == '-'))
                ++j;
            const std::string& token = hostile[static_cast<std::size_t>(replaced) % hostile.size()];
            const std::string m = text.substr(0, i) + token + text.substr(j);
            const int r = attempt(m, name + " number at " + std::to_string(i) + " -> " + token);
            parsed += r == 0, refused += r == 1, ++inputs;
            ++replaced;
            i = j;
        }
        // Chunks deleted or repeated.
        for (int k = 0; k < 40; ++k) {
            std::size_t a = pos(rng), b = pos(rng);
            if (a > b) std::swap(a, b);
            const std::string m = k % 2 ? text.substr(0, a) + text.substr(b) : text.substr(0, b) + text.substr(a);
            const int r = attempt(m, name + " chunk " + std::to_string(k));
            parsed += r == 0, refused += r == 1, ++inputs;
        }
    }
    EXPECT_EQ(parsed + refused, inputs);
    EXPECT_GT(refused, inputs / 2);  // the mutants are mostly invalid...
    EXPECT_GT(parsed, 0);             // ...and some survive (flips inside comments and strings)
}

// Deep nesting (once two minutes and gigabytes for 100000 levels: each level kept its path)
// and huge inputs: refused quickly, never a stack overflow or a hang.
TEST(SceneMutations, DeepNestingAndHugeArraysAreRefused) {
    EXPECT_EQ(attempt(std::string(100000, '[') + std::string(100000, ']'), "deep array"), 1);
    std::string deep;
    for (int i = 0; i < 20000; ++i) deep += "{\"a\":";
    deep += "1" + std::string(20000, '}');
    EXPECT_EQ(attempt(deep, "deep object"), 1);
    try {
        parseScene(R"({"strings": [{"name": "r", "points": )" + std::string(70, '[') + std::string(70, ']') + "}]}");
        ADD_FAILURE() << "accepted";
    } catch (const tearables::InvalidInput& e) {
        EXPECT_EQ(e.problem(), "nested deeper than 64 levels") << e.what();
        EXPECT_EQ(e.field().rfind("strings[0].points[0][0]", 0), 0u) << e.what();
    }
    std::string wide = "{\"strings\": [{\"name\": \"r\", \"points\": [";
    for (int i = 0; i < 50000; ++i) wide += "[0, 0, " + std::to_string(i) + "],";
    wide += "[0, 0, 0]]}]}";  // the last point coincides with the first: a valid geometry otherwise
    EXPECT_LE(attempt(wide, "50000 points"), 1);
}

}  // namespace
