// Compiled by CTest with BT_USE_DOUBLE_PRECISION against the plugin's single-precision
// headers: bullet.hpp must refuse it with its static_assert.
#include <tearables/bullet.hpp>
