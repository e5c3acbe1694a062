// Config and FIS definition loading (toml++). Validation is driven by common/config/schema.toml,
// the same file the host validates against, so every range is written once.
#include "config.hpp"

#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <algorithm>
#include <vector>

#include <toml++/toml.h>

#include "fuzzystereo/stages.hpp"

extern const char* const fs_embedded_fis_toml;
extern const char* const fs_embedded_default_toml;
extern const char* const fs_embedded_schema_toml;

namespace fs {

const char* embedded_default_config() { return fs_embedded_default_toml; }
const char* embedded_fis_definition() { return fs_embedded_fis_toml; }
const char* embedded_config_schema() { return fs_embedded_schema_toml; }

namespace {

std::string read_text_file(const std::string& path, const char* what) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ConfigError(std::string("cannot read ") + what + " '" + path + "': no such file or not readable");
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

toml::table parse_toml(const std::string& text, const std::string& source) {
  try {
    return toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    std::ostringstream ss;
    ss << source << ":" << e.source().begin.line << ":" << e.source().begin.column << ": TOML syntax error: "
       << e.description();
    throw ConfigError(ss.str());
  }
}

struct FieldSpec {
  std::string type;
  bool has_min = false, has_max = false, odd = false;
  double min = 0, max = 0;
  std::vector<std::string> choices;  // type == "string": allowed values (empty = any)
  std::string unit, doc;
};

// Schema fields in file order (for config_to_toml) and by name.
std::vector<std::string>& schema_order() {
  static std::vector<std::string> order;
  return order;
}

const std::map<std::string, FieldSpec>& schema() {
  static const std::map<std::string, FieldSpec> s = [] {
    std::map<std::string, FieldSpec> m;
    const toml::table t = parse_toml(fs_embedded_schema_toml, "schema.toml");
    for (auto&& [sec, secnode] : t) {
      for (auto&& [key, node] : *secnode.as_table()) {
        const auto& f = *node.as_table();
        FieldSpec spec;
        spec.type = f["type"].value_or(std::string("int"));
        if (auto v = f["min"].value<double>()) { spec.has_min = true; spec.min = *v; }
        if (auto v = f["max"].value<double>()) { spec.has_max = true; spec.max = *v; }
        spec.odd = f["odd"].value_or(false);
        if (const toml::array* c = f["choices"].as_array())
          for (auto&& e : *c) spec.choices.push_back(e.value_or(std::string()));
        spec.unit = f["unit"].value_or(std::string());
        spec.doc = f["doc"].value_or(std::string());
        const std::string name = std::string(sec.str()) + "." + std::string(key.str());
        m[name] = spec;
        schema_order().push_back(name);
      }
    }
    return m;
  }();
  return s;
}

std::string fmt_num(double v) {
  std::ostringstream ss;
  ss << v;
  return ss.str();
}

std::string range_text(const FieldSpec& s) {
  if (s.type == "string") {
    if (s.choices.empty()) return "string";
    std::string r = "one of";
    for (std::size_t i = 0; i < s.choices.size(); ++i) r += (i ? ", \"" : " \"") + s.choices[i] + "\"";
    return r;
  }
  std::string r = s.type;
  if (s.has_min || s.has_max) r += " in [" + fmt_num(s.min) + ", " + fmt_num(s.max) + "]";
  if (s.odd) r += ", odd";
  if (!s.unit.empty()) r += " " + s.unit;
  return r;
}

using Values = ConfigValues;

void collect(const toml::table& t, const std::string& source, Values& out) {
  const auto& sch = schema();
  for (auto&& [sec, secnode] : t) {
    const std::string secname(sec.str());
    const toml::table* st = secnode.as_table();
    if (!st) throw ConfigError(source + ": '" + secname + "' must be a table [" + secname + "]");
    for (auto&& [key, node] : *st) {
      const std::string name = secname + "." + std::string(key.str());
      auto it = sch.find(name);
      if (it == sch.end()) throw ConfigError(source + ": unknown field '" + name + "' (see common/config/schema.toml)");
      const FieldSpec& s = it->second;
      double v = 0;
      if (s.type == "string") {
        if (!node.is_string()) throw ConfigError(source + ": field '" + name + "' must be a string (" + range_text(s) + ")");
        const std::string sv = node.as_string()->get();
        if (!s.choices.empty() && std::find(s.choices.begin(), s.choices.end(), sv) == s.choices.end())
          throw ConfigError(source + ": field '" + name + "' = \"" + sv + "\" is not valid: " + range_text(s) + " (" +
                            s.doc + ")");
        out.strs[name] = sv;
        continue;
      } else if (s.type == "bool") {
        if (!node.is_boolean()) throw ConfigError(source + ": field '" + name + "' must be true or false");
        v = node.as_boolean()->get() ? 1 : 0;
      } else if (s.type == "int") {
        if (!node.is_integer()) throw ConfigError(source + ": field '" + name + "' must be an integer (" + range_text(s) + ")");
        v = static_cast<double>(node.as_integer()->get());
      } else {
        if (node.is_integer()) v = static_cast<double>(node.as_integer()->get());
        else if (node.is_floating_point()) v = node.as_floating_point()->get();
        else throw ConfigError(source + ": field '" + name + "' must be a number (" + range_text(s) + ")");
        if (!std::isfinite(v)) throw ConfigError(source + ": field '" + name + "' must be finite (" + range_text(s) + ")");
      }
      if ((s.has_min && v < s.min) || (s.has_max && v > s.max) ||
          (s.odd && std::fmod(std::fabs(v), 2.0) != 1.0))
        throw ConfigError(source + ": field '" + name + "' = " + fmt_num(v) + " is out of range: valid " + range_text(s) +
                          " (" + s.doc + ")");
      out.nums[name] = v;
    }
  }
}

MatcherParams to_params(const Values& v) {
  auto i = [&](const char* k) { return v.integer(k); };
  MatcherParams p;
  p.seg.region_size = i("segmentation.region_size");
  p.seg.compactness = i("segmentation.compactness");
  p.seg.iterations = i("segmentation.iterations");
  p.seg.coarse_iterations = i("segmentation.coarse_iterations");
  p.seg.min_segment_pct = i("segmentation.min_segment_pct");
  p.cost.max_disparity = i("cost.max_disparity");
  p.cost.alpha = v.num("cost.alpha");
  p.cost.nmi_bins = i("cost.nmi_bins");
  p.cost.nmi_candidates = i("cost.nmi_candidates");
  p.cost.subpixel = v.flag("cost.subpixel");
  p.cost.subpixel_every_segment = v.flag("cost.subpixel_every_segment");
  p.cost.gradient_gain_compensation = v.flag("cost.gradient_gain_compensation");
  p.cost.gradient_gain_deadband = v.num("cost.gradient_gain_deadband");
  p.cost.gradient_gain_trigger = v.str("cost.gradient_gain_trigger") == "gradient" ? GainTrigger::Gradient : GainTrigger::Grey;
  p.cost.gradient_gain_grey_shift = v.num("cost.gradient_gain_grey_shift");
  p.cost.noise_excess = v.num("cost.noise_excess");
  p.cost.noise_image_passes = i("cost.noise_image_passes");
  p.cost.noise_gradient_passes = i("cost.noise_gradient_passes");
  p.cost.inject_shift = i("testing.inject_shift");
  p.fis.lut_size = i("fis.lut_size");
  p.boundary.enabled = v.flag("boundary.enabled");
  p.boundary.on_mismatch = v.flag("boundary.on_mismatch");
  p.boundary.census_radius = i("boundary.census_radius");
  p.boundary.window = i("boundary.window");
  p.boundary.margin = v.num("boundary.margin");
  p.boundary.step = i("boundary.step");
  p.boundary.min_jump = i("boundary.min_jump");
  p.boundary.passes = i("boundary.passes");
  p.lr.max_diff = i("lr_check.max_diff");
  p.lr.retry_candidates = i("lr_check.retry_candidates");
  p.lr.retry_min_share = v.num("lr_check.retry_min_share");
  p.esr.enabled = v.flag("esr.enabled");
  p.esr.window = i("esr.window");
  p.esr.tau = v.num("esr.tau");
  {
    const std::string k = v.str("esr.kernel");  // one of the schema's choices (checked above)
    p.esr.kernel = k == "sliding" ? EntropyKernel::kSliding : k == "sorted" ? EntropyKernel::kSorted : EntropyKernel::kAuto;
  }
  p.densify.enabled = v.flag("densify.enabled");
  p.densify.speckle_max_size = i("densify.speckle_max_size");
  p.densify.speckle_max_diff = i("densify.speckle_max_diff");
  p.densify.fill = v.flag("densify.fill");
  p.densify.interpolate_max_diff = i("densify.interpolate_max_diff");
  p.densify.occlusion_fill = v.flag("densify.occlusion_fill");
  p.densify.occlusion_dilate = i("densify.occlusion_dilate");
  p.densify.occlusion_max_gap = i("densify.occlusion_max_gap");
  p.densify.border_fit_px = i("densify.border_fit_px");
  p.densify.border_fit_min_slope = v.num("densify.border_fit_min_slope");
  p.densify.smooth = v.flag("densify.smooth");
  p.densify.smoothing.radius = i("densify.smooth_radius");
  p.densify.smoothing.step = i("densify.smooth_step");
  p.densify.smoothing.sigma_space = v.num("densify.smooth_sigma_space");
  p.densify.smoothing.sigma_range = v.num("densify.smooth_sigma_range");
  p.densify.smoothing.sigma_range_rel = v.num("densify.smooth_sigma_range_rel");
  if (p.densify.smoothing.radius / p.densify.smoothing.step > kMaxSmoothReach)
    throw ConfigError(v.source + ": fields 'densify.smooth_radius' = " + std::to_string(p.densify.smoothing.radius) +
                      " and 'densify.smooth_step' = " + std::to_string(p.densify.smoothing.step) +
                      ": smooth_radius / smooth_step must be <= " + std::to_string(kMaxSmoothReach) +
                      " (at most 11 x 11 taps)");
  p.runtime.threads = i("runtime.threads");
  return p;
}

}  // namespace

double ConfigValues::num(const std::string& key) const {
  auto it = nums.find(key);
  if (it == nums.end()) throw ConfigError("config field '" + key + "' is not a numeric schema field (build error)");
  return it->second;
}
int ConfigValues::integer(const std::string& key) const { return static_cast<int>(num(key)); }
bool ConfigValues::flag(const std::string& key) const { return num(key) != 0.0; }
const std::string& ConfigValues::str(const std::string& key) const {
  auto it = strs.find(key);
  if (it == strs.end()) throw ConfigError("config field '" + key + "' is not a string schema field (build error)");
  return it->second;
}

Config parse_config(const std::string& toml_text, const std::string& source_name) {
  Config c;
  collect(parse_toml(fs_embedded_default_toml, "default.toml"), "default.toml", c.values);
  for (const auto& [name, spec] : schema())
    if (!c.values.nums.count(name) && !c.values.strs.count(name))
      throw ConfigError("default.toml: field '" + name + "' is missing (build error)");
  if (!toml_text.empty()) collect(parse_toml(toml_text, source_name), source_name, c.values);
  c.values.source = toml_text.empty() ? "default.toml" : source_name;
  c.matcher = to_params(c.values);
  return c;
}

Config load_config(const std::string& path) {
  if (path.empty()) return parse_config("", "default.toml");
  return parse_config(read_text_file(path, "config file"), path);
}

MatcherParams parse_matcher_config(const std::string& toml_text, const std::string& source_name) {
  return parse_config(toml_text, source_name).matcher;
}

MatcherParams load_matcher_config(const std::string& path) { return load_config(path).matcher; }

std::string config_to_toml(const ConfigValues& v) {
  schema();
  std::ostringstream s;
  std::string section;
  for (const std::string& name : schema_order()) {
    const std::string sec = name.substr(0, name.find('.'));
    const std::string key = name.substr(name.find('.') + 1);
    if (sec != section) {
      s << (section.empty() ? "" : "\n") << "[" << sec << "]\n";
      section = sec;
    }
    const FieldSpec& f = schema().at(name);
    s << key << " = ";
    if (f.type == "string") {
      s << '"';
      for (char ch : v.str(name)) {
        if (ch == '"' || ch == '\\') s << '\\';
        s << ch;
      }
      s << '"';
    } else if (f.type == "bool") {
      s << (v.flag(name) ? "true" : "false");
    } else if (f.type == "int") {
      s << static_cast<long long>(v.num(name));
    } else {
      const double x = v.num(name);
      s << fmt_num(x) << (x == std::floor(x) ? ".0" : "");
    }
    s << "\n";
  }
  return s.str();
}

std::string config_to_toml(const MatcherParams& p) {
  std::ostringstream s;
  s << "[segmentation]\nregion_size = " << p.seg.region_size << "\ncompactness = " << p.seg.compactness
    << "\niterations = " << p.seg.iterations << "\ncoarse_iterations = " << p.seg.coarse_iterations
    << "\nmin_segment_pct = " << p.seg.min_segment_pct << "\n\n"
    << "[cost]\nmax_disparity = " << p.cost.max_disparity << "\nalpha = " << fmt_num(p.cost.alpha)
    << (p.cost.alpha == std::floor(p.cost.alpha) ? ".0" : "") << "\nnmi_bins = " << p.cost.nmi_bins
    << "\nnmi_candidates = " << p.cost.nmi_candidates << "\nsubpixel = " << (p.cost.subpixel ? "true" : "false")
    << "\nsubpixel_every_segment = " << (p.cost.subpixel_every_segment ? "true" : "false")
    << "\ngradient_gain_compensation = " << (p.cost.gradient_gain_compensation ? "true" : "false")
    << "\ngradient_gain_deadband = " << fmt_num(p.cost.gradient_gain_deadband)
    << (p.cost.gradient_gain_deadband == std::floor(p.cost.gradient_gain_deadband) ? ".0" : "")
    << "\ngradient_gain_trigger = \"" << (p.cost.gradient_gain_trigger == GainTrigger::Gradient ? "gradient" : "grey") << "\""
    << "\ngradient_gain_grey_shift = " << fmt_num(p.cost.gradient_gain_grey_shift)
    << (p.cost.gradient_gain_grey_shift == std::floor(p.cost.gradient_gain_grey_shift) ? ".0" : "")
    << "\nnoise_excess = " << fmt_num(p.cost.noise_excess) << (p.cost.noise_excess == std::floor(p.cost.noise_excess) ? ".0" : "")
    << "\nnoise_image_passes = " << p.cost.noise_image_passes
    << "\nnoise_gradient_passes = " << p.cost.noise_gradient_passes << "\n\n"
    << "[fis]\nlut_size = " << p.fis.lut_size << "\n\n"
    << "[boundary]\nenabled = " << (p.boundary.enabled ? "true" : "false")
    << "\non_mismatch = " << (p.boundary.on_mismatch ? "true" : "false")
    << "\ncensus_radius = " << p.boundary.census_radius << "\nwindow = " << p.boundary.window
    << "\nmargin = " << fmt_num(p.boundary.margin) << (p.boundary.margin == std::floor(p.boundary.margin) ? ".0" : "")
    << "\nstep = " << p.boundary.step << "\nmin_jump = " << p.boundary.min_jump << "\npasses = " << p.boundary.passes
    << "\n\n"
    << "[lr_check]\nmax_diff = " << p.lr.max_diff << "\nretry_candidates = " << p.lr.retry_candidates
    << "\nretry_min_share = " << fmt_num(p.lr.retry_min_share)
    << (p.lr.retry_min_share == std::floor(p.lr.retry_min_share) ? ".0" : "") << "\n\n"
    << "[esr]\nenabled = " << (p.esr.enabled ? "true" : "false") << "\nwindow = " << p.esr.window
    << "\ntau = " << fmt_num(p.esr.tau) << (p.esr.tau == std::floor(p.esr.tau) ? ".0" : "")
    << "\nkernel = \"" << (p.esr.kernel == EntropyKernel::kSliding ? "sliding" : p.esr.kernel == EntropyKernel::kAuto ? "auto" : "sorted")
    << "\"\n\n"
    << "[densify]\nenabled = " << (p.densify.enabled ? "true" : "false")
    << "\nspeckle_max_size = " << p.densify.speckle_max_size << "\nspeckle_max_diff = " << p.densify.speckle_max_diff
    << "\nfill = " << (p.densify.fill ? "true" : "false") << "\ninterpolate_max_diff = " << p.densify.interpolate_max_diff
    << "\nocclusion_fill = " << (p.densify.occlusion_fill ? "true" : "false")
    << "\nocclusion_dilate = " << p.densify.occlusion_dilate << "\nocclusion_max_gap = " << p.densify.occlusion_max_gap
    << "\nborder_fit_px = " << p.densify.border_fit_px << "\nborder_fit_min_slope = " << fmt_num(p.densify.border_fit_min_slope)
    << (p.densify.border_fit_min_slope == std::floor(p.densify.border_fit_min_slope) ? ".0" : "")
    << "\nsmooth = " << (p.densify.smooth ? "true" : "false") << "\nsmooth_radius = " << p.densify.smoothing.radius
    << "\nsmooth_step = " << p.densify.smoothing.step << "\nsmooth_sigma_space = " << fmt_num(p.densify.smoothing.sigma_space)
    << (p.densify.smoothing.sigma_space == std::floor(p.densify.smoothing.sigma_space) ? ".0" : "")
    << "\nsmooth_sigma_range = " << fmt_num(p.densify.smoothing.sigma_range)
    << (p.densify.smoothing.sigma_range == std::floor(p.densify.smoothing.sigma_range) ? ".0" : "")
    << "\nsmooth_sigma_range_rel = " << fmt_num(p.densify.smoothing.sigma_range_rel)
    << (p.densify.smoothing.sigma_range_rel == std::floor(p.densify.smoothing.sigma_range_rel) ? ".0" : "") << "\n\n"
    << "[runtime]\nthreads = " << p.runtime.threads << "\n\n"
    << "[testing]\ninject_shift = " << p.cost.inject_shift << "\n";
  return s.str();
}

// ---- FIS definition -----------------------------------------------------------------------------

namespace {

FisVariable parse_variable(const toml::table& t, const std::string& name, const std::string& src) {
  FisVariable v;
  v.name = name;
  const toml::array* terms = t["terms"].as_array();
  if (!terms || terms->empty()) throw ConfigError(src + ": variable '" + name + "' has no 'terms' array");
  std::set<std::string> seen;
  for (auto&& n : *terms) {
    const toml::table* tt = n.as_table();
    if (!tt) throw ConfigError(src + ": variable '" + name + "': every term must be { name, mf, params }");
    FisTerm term;
    term.name = (*tt)["name"].value_or(std::string());
    term.mf = (*tt)["mf"].value_or(std::string());
    const std::string where = src + ": term '" + name + "." + term.name + "'";
    if (term.name.empty()) throw ConfigError(src + ": variable '" + name + "' has a term without a name");
    if (!seen.insert(term.name).second) throw ConfigError(where + " is defined twice");
    if (term.mf != "trimf" && term.mf != "trapmf")
      throw ConfigError(where + ": mf '" + term.mf + "' is not supported (valid: trimf, trapmf)");
    const toml::array* pa = (*tt)["params"].as_array();
    const std::size_t want = term.mf == "trimf" ? 3 : 4;
    if (!pa || pa->size() != want)
      throw ConfigError(where + ": params must be " + std::to_string(want) + " numbers for " + term.mf);
    for (auto&& pn : *pa) {
      auto x = pn.value<double>();
      if (!x || *x < 0.0 || *x > 1.0) throw ConfigError(where + ": params must be numbers in [0, 1]");
      term.params.push_back(*x);
    }
    for (std::size_t i = 1; i < term.params.size(); ++i)
      if (term.params[i] < term.params[i - 1]) throw ConfigError(where + ": params must be non-decreasing");
    v.terms.push_back(term);
  }
  return v;
}

int term_index(const FisVariable& v, const std::string& term, const std::string& src, std::int64_t rule) {
  for (std::size_t i = 0; i < v.terms.size(); ++i)
    if (v.terms[i].name == term) return static_cast<int>(i);
  throw ConfigError(src + ": rule " + std::to_string(rule) + ": '" + term + "' is not a term of '" + v.name + "'");
}

}  // namespace

FisDefinition parse_fis_definition(const std::string& text, const std::string& src) {
  const toml::table t = parse_toml(text, src);
  FisDefinition d;
  d.name = t["name"].value_or(std::string("unnamed"));
  d.input_points = static_cast<int>(t["universe"]["input_points"].value_or(std::int64_t(1001)));
  d.output_points = static_cast<int>(t["universe"]["output_points"].value_or(std::int64_t(1401)));
  if (d.input_points < 11 || d.input_points > 100001) throw ConfigError(src + ": universe.input_points must be in [11, 100001]");
  if (d.output_points < 11 || d.output_points > 100001) throw ConfigError(src + ": universe.output_points must be in [11, 100001]");
  const toml::table* in1 = t["inputs"]["dc1"].as_table();
  const toml::table* in2 = t["inputs"]["dc2"].as_table();
  const toml::table* out = t["output"].as_table();
  if (!in1 || !in2 || !out) throw ConfigError(src + ": needs tables [inputs.dc1], [inputs.dc2] and [output]");
  d.in1 = parse_variable(*in1, "dc1", src);
  d.in2 = parse_variable(*in2, "dc2", src);
  d.out = parse_variable(*out, (*out)["name"].value_or(std::string("score")), src);
  const toml::array* rules = (*out)["rules"].as_array();
  if (!rules) rules = t["rules"].as_array();
  if (!rules || rules->empty()) throw ConfigError(src + ": no 'rules' array");
  std::set<std::pair<int, int>> pairs;
  for (auto&& rn : *rules) {
    const toml::array* r = rn.as_array();
    if (!r || r->size() != 4) throw ConfigError(src + ": every rule must be [number, dc1 term, dc2 term, output term]");
    FisRule rule;
    const std::int64_t num = (*r)[0].value_or(std::int64_t(0));
    rule.number = static_cast<int>(num);
    rule.in1 = term_index(d.in1, (*r)[1].value_or(std::string()), src, num);
    rule.in2 = term_index(d.in2, (*r)[2].value_or(std::string()), src, num);
    rule.out = term_index(d.out, (*r)[3].value_or(std::string()), src, num);
    if (!pairs.insert({rule.in1, rule.in2}).second)
      throw ConfigError(src + ": rule " + std::to_string(num) + " repeats the antecedent pair of an earlier rule");
    d.rules.push_back(rule);
  }
  return d;
}

FisDefinition load_fis_definition(const std::string& path) {
  if (path.empty()) return parse_fis_definition(fs_embedded_fis_toml, "fis.toml (built in)");
  return parse_fis_definition(read_text_file(path, "FIS definition"), path);
}

}  // namespace fs
