// Random scenario generator for synthetic stereo data sets (docs/simulator.md, "Generator").
// Deterministic: scene i of a set depends only on (set seed, i, options); the random numbers come
// from std::mt19937_64 (its output sequence is fixed by the C++ standard) turned into doubles by
// hand, never through std::*_distribution (implementation-defined).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "fuzzystereo/sim/scene.hpp"

namespace fs::sim {

// Version of the generator's distributions, written into the set marker; bump it whenever a
// change makes the same (seed, index) give a different scene.
inline constexpr int kGeneratorVersion = 1;

struct GeneratorOptions {
  int width = 640, height = 360;  // image size; focal_px scales with the width (same field of view)
};

// Scenario types, spread evenly over a set (index i gets type i % size).
const std::vector<std::string>& scenario_types();

// Scene `index` of the set with seed `set_seed`. Values are rounded (mm, 0.1 deg, 1e-3) so the
// scene file reads well; render the scene as re-parsed from scene_to_toml() for bit-identical
// reproduction from the written file.
Scene generate_scene(std::uint64_t set_seed, int index, const GeneratorOptions& opt);

}  // namespace fs::sim
