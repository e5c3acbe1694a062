// Google Benchmark micro-benchmarks of the matcher stages on a KITTI-sized synthetic pair
// (1242 x 375, D = 160): the per-stage figures behind `fuzzystereo bench`, without OpenCV or the
// datasets. Run: build/default/tests/bench/fs_core_bench [--benchmark_filter=Slic]
// Single-threaded (runtime.threads = 1) so the numbers are per core.
#include <benchmark/benchmark.h>

#include <random>

#if defined(FS_HAVE_OPENMP)
#include <omp.h>
#endif

#include "config.hpp"
#include "fuzzystereo/fis.hpp"
#include "fuzzystereo/matcher.hpp"
#include "fuzzystereo/memory.hpp"
#include "fuzzystereo/stages.hpp"

namespace {

constexpr int kW = 1242, kH = 375, kD = 160;

// Smooth random texture (two box blurs of uniform noise), right = left shifted by a disparity
// that grows towards the bottom rows (a road-like slant) plus a near block.
struct Pair {
  fs::ImageU8 left{kW, kH}, right{kW, kH};
  Pair() {
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> u(0, 255);
    const int WW = kW + kD;
    std::vector<int> a(std::size_t(WW) * kH), b(a.size());
    for (auto& v : a) v = u(rng);
    for (int pass = 0; pass < 2; ++pass) {
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < WW; ++x) {
          int s = 0, n = 0;
          for (int k = -1; k <= 1; ++k)
            for (int j = -1; j <= 1; ++j) {
              const int yy = std::clamp(y + k, 0, kH - 1), xx = std::clamp(x + j, 0, WW - 1);
              s += a[std::size_t(yy) * WW + xx];
              ++n;
            }
          b[std::size_t(y) * WW + x] = s / n;
        }
      a.swap(b);
    }
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        int d = 5 + (y * 80) / kH;
        if (x > 500 && x < 700 && y > 150 && y < 300) d = 110;
        left.at(x, y) = static_cast<std::uint8_t>(a[std::size_t(y) * WW + x + kD]);
        right.at(x, y) = static_cast<std::uint8_t>(a[std::size_t(y) * WW + std::max(0, x + kD - d)]);
      }
  }
};

const Pair& pair() {
#if defined(FS_HAVE_OPENMP)
  omp_set_num_threads(1);  // stage functions called directly open their own parallel regions
#endif
  static const Pair p;
  return p;
}

fs::MatcherParams params() {
  fs::MatcherParams p;  // library defaults, D = 160, one thread
  p.cost.max_disparity = kD;
  p.runtime.threads = 1;
  return p;
}

const fs::FisLut& lut() {
  static const auto l = fs::FisLut::cached(fs::load_fis_definition(""), params().fis.lut_size);
  return *l;
}

void BM_Gradient(benchmark::State& st) {
  for (auto _ : st) benchmark::DoNotOptimize(fs::gradient_magnitude(pair().left));
}
BENCHMARK(BM_Gradient)->Unit(benchmark::kMillisecond);

// The noise equalisation detector (docs/algorithm.md 2c) runs on every frame: both images.
void BM_NoiseDetector(benchmark::State& st) {
  for (auto _ : st)
    benchmark::DoNotOptimize(fs::noise_excess(fs::estimate_noise_sigma(pair().left), fs::estimate_noise_sigma(pair().right),
                                              fs::grey_spread(pair().left), fs::grey_spread(pair().right)));
}
BENCHMARK(BM_NoiseDetector)->Unit(benchmark::kMillisecond);

void BM_Slic(benchmark::State& st) {
  const auto p = params();
  for (auto _ : st) benchmark::DoNotOptimize(fs::slic_segment(pair().left, p.seg));
}
BENCHMARK(BM_Slic)->Unit(benchmark::kMillisecond);

void BM_CostLeft(benchmark::State& st) {
  const auto p = params();
  const auto gl = fs::gradient_magnitude(pair().left), gr = fs::gradient_magnitude(pair().right);
  const auto seg = fs::slic_segment(pair().left, p.seg);
  auto scratch = fs::make_cost_scratch();
  (void)lut();  // built outside the timed loop (its first use takes ~0.5 s)
  for (auto _ : st)
    benchmark::DoNotOptimize(
        fs::compute_segment_costs(pair().left, pair().right, gl, gr, seg, +1, p.cost, lut(), 1, scratch.get()));
}
BENCHMARK(BM_CostLeft)->Unit(benchmark::kMillisecond);

void BM_WtaLeft(benchmark::State& st) {
  const auto p = params();
  const auto gl = fs::gradient_magnitude(pair().left), gr = fs::gradient_magnitude(pair().right);
  const auto seg = fs::slic_segment(pair().left, p.seg);
  const auto c = fs::compute_segment_costs(pair().left, pair().right, gl, gr, seg, +1, p.cost, lut(), 1);
  for (auto _ : st) {
    auto dec = fs::fis_winner_take_all(c, lut(), p.cost);
    benchmark::DoNotOptimize(fs::paint_segments(seg, dec.disparity_q4));
  }
}
BENCHMARK(BM_WtaLeft)->Unit(benchmark::kMillisecond);

// The segment-boundary refinement of both WTA maps (docs/algorithm.md 4b, [boundary] defaults of
// the section) with its census transforms, as the matcher runs it when `[boundary] enabled`.
void BM_Boundary(benchmark::State& st) {
  const fs::Matcher m(params(), fs::load_fis_definition(""));
  const auto r = m.match(pair().left, pair().right);
  fs::BoundaryParams bp;
  bp.enabled = true;
  for (auto _ : st) {
    const auto cl = fs::census_transform(pair().left, bp.census_radius), cr = fs::census_transform(pair().right, bp.census_radius);
    benchmark::DoNotOptimize(fs::refine_boundaries(r.disp_left_wta, r.seg_left, cl, cr, +1, bp, nullptr));
    benchmark::DoNotOptimize(fs::refine_boundaries(r.disp_right_wta, r.seg_right, cr, cl, -1, bp, nullptr));
  }
}
BENCHMARK(BM_Boundary)->Unit(benchmark::kMillisecond);

void BM_LrCheck(benchmark::State& st) {
  const fs::Matcher m(params(), fs::load_fis_definition(""));
  const auto r = m.match(pair().left, pair().right);
  fs::ImageU8 mask;
  for (auto _ : st) benchmark::DoNotOptimize(fs::left_right_check(r.disp_left_wta, r.disp_right_wta, params().lr, &mask));
}
BENCHMARK(BM_LrCheck)->Unit(benchmark::kMillisecond);

void BM_Esr(benchmark::State& st) {
  const auto p = params();
  const fs::Matcher m(p, fs::load_fis_definition(""));
  const auto r = m.match(pair().left, pair().right);
  for (auto _ : st)
    benchmark::DoNotOptimize(fs::entropy_selective_refinement(r.disp_lr, r.disp_right_wta, p.esr, kD, nullptr));
}
BENCHMARK(BM_Esr)->Unit(benchmark::kMillisecond);

// First arg 0: the left map after eq. (13); 1: the right-reference WTA map (no eq. (13) holes), ESR's
// other entropy image. Second arg: the kernel (0 kAuto, 1 kSliding, 2 kSorted, 3 kSortedPortable; fs::EntropyKernel).
void BM_BlockEntropy(benchmark::State& st) {
  const auto p = params();
  const fs::Matcher m(p, fs::load_fis_definition(""));
  const auto r = m.match(pair().left, pair().right);
  const fs::ImageI16& d = st.range(0) == 0 ? r.disp_lr : r.disp_right_wta;
  const auto kernel = static_cast<fs::EntropyKernel>(st.range(1));
  for (auto _ : st) benchmark::DoNotOptimize(fs::block_entropy(d, p.esr.window, kD, nullptr, kernel));
}
BENCHMARK(BM_BlockEntropy)->ArgsProduct({{0, 1}, {0, 1, 2}})->Unit(benchmark::kMillisecond);

void BM_Densify(benchmark::State& st) {
  const auto p = params();
  const fs::Matcher m(p, fs::load_fis_definition(""));
  const auto r = m.match(pair().left, pair().right);
  for (auto _ : st) benchmark::DoNotOptimize(fs::densify(r.disp_esr, p.densify, nullptr, &r.disp_right_wta));
}
BENCHMARK(BM_Densify)->Unit(benchmark::kMillisecond);

// The occlusion fill alone (docs/algorithm.md 6c), on the ESR map.
void BM_OcclusionFill(benchmark::State& st) {
  const auto p = params();
  const fs::Matcher m(p, fs::load_fis_definition(""));
  const auto r = m.match(pair().left, pair().right);
  for (auto _ : st) {
    fs::ImageI16 d = r.disp_esr;
    benchmark::DoNotOptimize(fs::occlusion_fill(d, r.disp_right_wta, p.densify.occlusion_dilate, p.densify.occlusion_max_gap, nullptr));
  }
}
BENCHMARK(BM_OcclusionFill)->Unit(benchmark::kMillisecond);

// The bilateral smoothing alone (docs/algorithm.md 6d), on the dense map.
void BM_Smooth(benchmark::State& st) {
  const auto p = params();
  const fs::Matcher m(p, fs::load_fis_definition(""));
  const auto r = m.match(pair().left, pair().right);
  for (auto _ : st) benchmark::DoNotOptimize(fs::smooth_disparity(r.disp_final, p.densify.smoothing));
}
BENCHMARK(BM_Smooth)->Unit(benchmark::kMillisecond);

// The plain 8-ray median fill (interpolate_max_diff = 0): the cost of the slant-aware fill.
void BM_DensifyPlainMedian(benchmark::State& st) {
  auto p = params();
  const fs::Matcher m(p, fs::load_fis_definition(""));
  const auto r = m.match(pair().left, pair().right);
  p.densify.interpolate_max_diff = 0;
  p.densify.occlusion_fill = false;
  for (auto _ : st) benchmark::DoNotOptimize(fs::densify(r.disp_esr, p.densify, nullptr));
}
BENCHMARK(BM_DensifyPlainMedian)->Unit(benchmark::kMillisecond);

void BM_Matcher(benchmark::State& st) {
  const fs::Matcher m(params(), fs::load_fis_definition(""));
  for (auto _ : st) benchmark::DoNotOptimize(m.match(pair().left, pair().right));
}
BENCHMARK(BM_Matcher)->Unit(benchmark::kMillisecond);

}  // namespace

// BENCHMARK_MAIN with the program's memory policy (fuzzystereo/memory.hpp), as `fuzzystereo` runs.
int main(int argc, char** argv) {
  fs::retain_freed_memory();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
