// A base header that includes the world above it: check_layers must refuse it.
#pragma once
#include "world/top.hpp"
