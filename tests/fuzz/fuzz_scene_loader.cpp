// libFuzzer target (issue 8): the scene loader on arbitrary bytes. parseScene must either
// return a scene or throw tearables::InvalidInput (its documented error); anything else
// (another exception, a crash, a sanitizer finding, a hang) is a bug the fuzzer reports.
// Built only with -DTEARABLES_FUZZ=ON and clang; see README.md, "Checks".
#include "tearables/scene.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        const tearables::scene::Scene scene = tearables::scene::parseScene(std::string(reinterpret_cast<const char*>(data), size));
        (void)scene;
    } catch (const tearables::InvalidInput&) {
        // the documented refusal
    }
    return 0;
}
