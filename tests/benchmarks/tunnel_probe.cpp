// tearables_tunnel_probe: does a fast body pass through a rope, sheet or cloth held at its
// ends or edges? Prints one row per shot of tests/tunnel_scenes.hpp:
// the outcome (stopped, tore, through) and the body's speed and height at the end. Not a
// test: docs/tunnelling.md keeps its table; tests/plugin/test_tunnelling.cpp holds the cases.
// Run: build/tests/benchmarks/tearables_tunnel_probe [dt]
// One shot traced step by step: tearables_tunnel_probe dt TARGET SHAPE MASS SPEED [SPIN],
// with TARGET rope, tearable, paper or cloth, SHAPE sphere or box and SPIN in rad/s about z.
#include "tunnel_scenes.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>

int main(int argc, char** argv) {
    using namespace tearables::tunnel;
    const double dt = argc > 1 ? std::atof(argv[1]) : 0.01;
    if (argc == 6 || argc == 7) {
        Shot shot;
        shot.dt = dt;
        const char* t = argv[2];
        shot.target = !std::strcmp(t, "paper")      ? Target::Paper
                      : !std::strcmp(t, "cloth")    ? Target::Cloth
                      : !std::strcmp(t, "tearable") ? Target::TearableRope
                                                    : Target::Rope;
        shot.shape = !std::strcmp(argv[3], "box") ? Shape::Box : Shape::Sphere;
        shot.mass = std::atof(argv[4]);
        shot.speed = std::atof(argv[5]);
        if (argc == 7) shot.spin = std::atof(argv[6]);
        const Outcome o = fire(shot, stdout);
        std::printf("%s%s%s; body's energy %.4g J at the start, %.4g J at most\n", o.through ? "THROUGH" : o.tore ? "tore" : "not through",
                    o.error.empty() ? "" : "; error: ", o.error.c_str(), o.start_energy, o.peak_energy);
        return 0;
    }
    std::printf("| target | body | mass kg | speed m/s | outcome | end speed m/s | end y m | peak T / rupture load |\n");
    std::printf("|---|---|---|---|---|---|---|---|\n");
    for (Target target : {Target::Rope, Target::TearableRope, Target::Paper, Target::Cloth})
        for (Shape shape : {Shape::Sphere, Shape::Box})
            for (double mass : {1.0, 100.0})
                for (double speed : {50.0, 100.0, 300.0, 500.0}) {
                    Shot shot;
                    shot.target = target;
                    shot.shape = shape;
                    shot.mass = mass;
                    shot.speed = speed;
                    shot.dt = dt;
                    const Outcome o = fire(shot);
                    const char* what = o.through ? "THROUGH" : o.tore ? "tore" : o.end_y < -o.half ? "stopped or turned aside" : "held or bounced";
                    char load[32] = "-";
                    if (o.rupture_load > 0) std::snprintf(load, sizeof load, "%.2f", o.peak_tension / o.rupture_load);
                    std::printf("| %s | %s | %g | %g | %s%s%s | %.1f | %.3f | %s |\n", name(target),
                                shape == Shape::Sphere ? "sphere r 1 cm" : "box 10 cm", mass, speed, what,
                                o.error.empty() ? "" : "; error: ", o.error.c_str(), o.end_speed, o.end_y, load);
                    std::fflush(stdout);
                }
    return 0;
}
