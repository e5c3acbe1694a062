// `fuzzystereo fis eval|dump`: expose the FIS lookup table so the host can check it against
// scikit-fuzzy (tests/python/test_fis.py, `fuzzyctl fis check`).
#include <cstdio>
#include <iostream>
#include <sstream>

#include "commands.hpp"
#include "config.hpp"
#include "fuzzystereo/fis.hpp"
#include "io.hpp"

namespace fs::app {

namespace {

struct FisOptions {
  std::string fis, config, out;
};

// Reads "dc1 dc2" pairs (floats in [0, 1]) from stdin; prints "lut exact" per pair.
void run_eval(const FisOptions& o) {
  const MatcherParams p = load_matcher_config(o.config);
  const FisDefinition def = load_fis_definition(o.fis);
  const FisLut lut(def, p.fis.lut_size);
  std::string line;
  int lineno = 0;
  while (std::getline(std::cin, line)) {
    ++lineno;
    std::istringstream ss(line);
    double a, b;
    if (!(ss >> a)) continue;  // blank line
    if (!(ss >> b) || a < 0.0 || a > 1.0 || b < 0.0 || b > 1.0)
      throw UserError("stdin line " + std::to_string(lineno) + ": expected two numbers in [0, 1], got '" + line + "'");
    const auto qa = static_cast<std::uint32_t>(std::llround(a * kQ16One));
    const auto qb = static_cast<std::uint32_t>(std::llround(b * kQ16One));
    std::printf("%.9f %.9f\n", static_cast<double>(lut.lookup(qa, qb)) / kQ16One, fis_evaluate(def, a, b));
  }
}

void run_dump(const FisOptions& o) {
  const MatcherParams p = load_matcher_config(o.config);
  const FisLut lut(load_fis_definition(o.fis), p.fis.lut_size);
  const std::size_t n = std::size_t(lut.size());
  write_npy(o.out, lut.table().data(), {n, n});
  std::printf("wrote %s (%zux%zu, uint32 Q16)\n", o.out.c_str(), n, n);
}

}  // namespace

void add_fis_command(CLI::App& app) {
  auto o = std::make_shared<FisOptions>();
  CLI::App* fis = app.add_subcommand("fis", "Fuzzy inference system tools");
  fis->require_subcommand(1);
  CLI::App* ev = fis->add_subcommand("eval", "Read 'dc1 dc2' lines on stdin, print 'lut exact' per line");
  CLI::App* du = fis->add_subcommand("dump", "Write the lookup table as .npy (uint32 Q16)");
  for (CLI::App* c : {ev, du}) {
    c->add_option("--fis", o->fis, "FIS definition TOML (default: built in)");
    c->add_option("--config", o->config, "config TOML (fis.lut_size)");
  }
  du->add_option("--out", o->out, "output .npy file")->required();
  ev->callback([o] { run_eval(*o); });
  du->callback([o] { run_dump(*o); });
}

}  // namespace fs::app
