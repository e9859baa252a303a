// The tension colour map: its order (luminance rises with load), its ends and its guards.
#include "tearables/colormap.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using tearables::loadFraction;
using tearables::luminance;
using tearables::Rgb;
using tearables::tensionColor;

// Luminance rises strictly over [0, 1] (1001 samples), so a brighter segment is always the
// more loaded one; channels stay in [0, 1].
TEST(Colormap, LuminanceRisesStrictlyWithLoad) {
    double previous = -1.0;
    for (int i = 0; i <= 1000; ++i) {
        const Rgb c = tensionColor(i / 1000.0);
        for (float ch : {c.r, c.g, c.b}) {
            EXPECT_GE(ch, 0.0f);
            EXPECT_LE(ch, 1.0f);
        }
        const double l = luminance(c);
        EXPECT_GT(l, previous) << "at u = " << i / 1000.0;
        previous = l;
    }
    // Slack is dark blue, about to tear is bright yellow.
    const Rgb slack = tensionColor(0.0), torn = tensionColor(1.0);
    EXPECT_GT(slack.b, slack.r);
    EXPECT_GT(torn.r, torn.b);
    EXPECT_GT(torn.g, torn.b);
    EXPECT_GT(luminance(torn) - luminance(slack), 0.7);
}

TEST(Colormap, ClampsAndGuards) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const auto same = [](const Rgb& a, const Rgb& b) { return a.r == b.r && a.g == b.g && a.b == b.b; };
    EXPECT_TRUE(same(tensionColor(-3.0), tensionColor(0.0)));
    EXPECT_TRUE(same(tensionColor(7.0), tensionColor(1.0)));
    EXPECT_TRUE(same(tensionColor(nan), tensionColor(0.0)));
    // loadFraction: T / (sigma_r pi r^2), clamped; 0 for nonsense.
    const double r = 0.002, sigma = 8e7, rupture_tension = sigma * M_PI * r * r;
    EXPECT_NEAR(loadFraction(0.25 * rupture_tension, sigma, r), 0.25, 1e-12);
    EXPECT_EQ(loadFraction(2.0 * rupture_tension, sigma, r), 1.0);
    EXPECT_EQ(loadFraction(-5.0, sigma, r), 0.0);  // compression draws as slack
    EXPECT_EQ(loadFraction(nan, sigma, r), 0.0);
    EXPECT_EQ(loadFraction(1.0, 0.0, r), 0.0);
}
