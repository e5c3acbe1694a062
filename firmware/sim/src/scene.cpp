// Scene file parsing and validation (toml++). One reader per table records the keys it consumed,
// so unknown keys are rejected with the list of valid ones; every numeric field has one range,
// written once here and repeated in docs/simulator.md.
#include "fuzzystereo/sim/scene.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <toml++/toml.h>

#include "config.hpp"  // fs::ConfigError

namespace fs::sim {
namespace {

const std::vector<std::string> kSkyNames{"clear", "overcast", "sunset"};
const std::vector<std::string> kGroundNames{"asphalt", "gravel", "grass", "tiles"};
const std::vector<std::string> kShapeNames{"box", "cylinder", "post"};
const std::vector<std::string> kTextureNames{"bricks", "noise", "stripes", "checker", "wood", "camo"};

// Shortest text that reads back to the same double (std::to_chars round-trip guarantee).
std::string num_text(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, r.ptr);
  return s;
}

// A numeric range with open/closed ends and a unit, printed as "float in (0, 2] m".
struct Range {
  double lo, hi;
  bool lo_open = false, hi_open = false;
  const char* unit = "";
  bool contains(double v) const {
    return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  }
  std::string text(const char* type) const {
    std::string r = std::string(type) + " in " + (lo_open ? "(" : "[") + num_text(lo) + ", " + num_text(hi) +
                    (hi_open ? ")" : "]");
    if (*unit) r += std::string(" ") + unit;
    return r;
  }
};

std::string choices_text(const std::vector<std::string>& names) {
  std::string r = "one of";
  for (std::size_t i = 0; i < names.size(); ++i) r += (i ? ", \"" : " \"") + names[i] + "\"";
  return r;
}

std::string node_text(const toml::node& n) {
  std::ostringstream ss;
  if (n.is_string()) ss << '"' << n.as_string()->get() << '"';
  else if (n.is_table()) ss << "a table";
  else if (n.is_array()) ss << "an array";
  else if (n.is_integer()) ss << n.as_integer()->get();
  else if (n.is_floating_point()) ss << num_text(n.as_floating_point()->get());
  else if (n.is_boolean()) ss << (n.as_boolean()->get() ? "true" : "false");
  else ss << "a date/time";
  return ss.str();
}

// Reads the fields of one table; `prefix` is "camera." or "obstacles[2]." for messages.
class Reader {
 public:
  Reader(const toml::table* t, std::string prefix, const std::string& source)
      : t_(t), prefix_(std::move(prefix)), source_(source) {}

  [[noreturn]] void fail(const std::string& msg) const { throw ConfigError(source_ + ": " + msg); }
  std::string name(const std::string& key) const { return prefix_ + key; }

  const toml::node* get(const std::string& key) {
    allowed_.insert(key);
    return t_ ? t_->get(key) : nullptr;
  }
  bool has(const std::string& key) const { return t_ && t_->get(key) != nullptr; }

  double num(const std::string& key, double def, const Range& r) {
    const toml::node* n = get(key);
    if (!n) return def;
    double v = 0.0;
    if (n->is_integer()) v = static_cast<double>(n->as_integer()->get());
    else if (n->is_floating_point()) v = n->as_floating_point()->get();
    else fail(name(key) + " = " + node_text(*n) + " has the wrong type: expected " + r.text("float"));
    if (!std::isfinite(v) || !r.contains(v))
      fail(name(key) + " = " + num_text(v) + " is out of range: " + r.text("float"));
    return v;
  }

  std::int64_t integer(const std::string& key, std::int64_t def, const Range& r) {
    const toml::node* n = get(key);
    if (!n) return def;
    if (!n->is_integer()) fail(name(key) + " = " + node_text(*n) + " has the wrong type: expected " + r.text("int"));
    const std::int64_t v = n->as_integer()->get();
    if (!r.contains(static_cast<double>(v)))
      fail(name(key) + " = " + std::to_string(v) + " is out of range: " + r.text("int"));
    return v;
  }

  // Index into `names` of the string at `key` (def when absent).
  int choice(const std::string& key, int def, const std::vector<std::string>& names) {
    const toml::node* n = get(key);
    if (!n) return def;
    if (!n->is_string())
      fail(name(key) + " = " + node_text(*n) + " has the wrong type: expected a string, " + choices_text(names));
    const std::string v = n->as_string()->get();
    const auto it = std::find(names.begin(), names.end(), v);
    if (it == names.end()) fail(name(key) + " = \"" + v + "\" is not valid: " + choices_text(names));
    return static_cast<int>(it - names.begin());
  }

  std::string str(const std::string& key, const std::string& def) {
    const toml::node* n = get(key);
    if (!n) return def;
    if (!n->is_string()) fail(name(key) + " = " + node_text(*n) + " has the wrong type: expected a string");
    return n->as_string()->get();
  }

  const toml::table* table(const std::string& key) {
    const toml::node* n = get(key);
    if (!n) return nullptr;
    if (!n->is_table()) fail(name(key) + " must be a table [" + name(key) + "], not " + node_text(*n));
    return n->as_table();
  }

  // Rejects keys that no accessor asked for.
  void finish() const {
    if (!t_) return;
    for (auto&& [k, v] : *t_) {
      const std::string key(k.str());
      if (allowed_.count(key)) continue;
      std::string valid;
      for (const auto& a : allowed_) valid += (valid.empty() ? "" : ", ") + a;
      fail("unknown field '" + name(key) + "' (valid: " + valid + ")");
    }
  }

 private:
  const toml::table* t_;
  std::string prefix_;
  const std::string& source_;
  std::set<std::string> allowed_;
};

constexpr double kBig = 1000.0;  // world extent [m]

CameraRadiometry read_radiometry(Reader& parent, const std::string& key, const std::string& source) {
  Reader r(parent.table(key), parent.name(key) + ".", source);
  CameraRadiometry c;
  c.gain = r.num("gain", c.gain, {0.0, 4.0, true, false, ""});
  c.gamma = r.num("gamma", c.gamma, {0.2, 5.0});
  c.bias = r.num("bias", c.bias, {-128.0, 128.0, false, false, "grey levels"});
  c.noise_sigma = r.num("noise_sigma", c.noise_sigma, {0.0, 64.0, false, false, "grey levels"});
  r.finish();
  return c;
}

ObstacleSpec read_obstacle(const toml::table* t, int index, const std::string& source) {
  const std::string prefix = "obstacles[" + std::to_string(index) + "].";
  Reader r(t, prefix, source);
  ObstacleSpec o;
  o.id = static_cast<int>(r.integer("id", -1, {0, 65534}));
  o.shape = static_cast<Shape>(r.choice("shape", 0, kShapeNames));
  o.x_m = r.num("x_m", 0.0, {-kBig, kBig, false, false, "m"});
  o.y_m = r.num("y_m", 0.0, {-kBig, kBig, false, false, "m"});
  if (const toml::node* z = t->get("z_m"); z && (z->is_integer() || z->is_floating_point())) {
    const double zv = z->is_integer() ? static_cast<double>(z->as_integer()->get()) : z->as_floating_point()->get();
    if (zv < 0.0) r.fail(prefix + "z_m = " + num_text(zv) + ": obstacle below ground (must be >= 0)");
  }
  o.z_m = r.num("z_m", 0.0, {0.0, 100.0, false, false, "m"});
  o.yaw_deg = r.num("yaw_deg", 0.0, {-360.0, 360.0, false, false, "deg"});
  const Range size{0.0, 50.0, true, false, "m"};
  switch (o.shape) {
    case Shape::Box:
      o.length_m = r.num("length_m", 0.6, size);
      o.width_m = r.num("width_m", 0.6, size);
      o.height_m = r.num("height_m", 0.6, size);
      break;
    case Shape::Cylinder:
      o.radius_m = r.num("radius_m", 0.3, {0.0, 25.0, true, false, "m"});
      o.height_m = r.num("height_m", 1.0, size);
      break;
    case Shape::Post:
      o.radius_m = r.num("radius_m", 0.25, {0.0, 25.0, true, false, "m"});
      o.height_m = r.num("height_m", 1.7, size);
      break;
  }
  for (const char* k : {"length_m", "width_m", "radius_m", "height_m"})
    if (r.has(k) && o.shape != Shape::Box && (std::string(k) == "length_m" || std::string(k) == "width_m"))
      r.fail(prefix + k + " is not a field of a " + to_string(o.shape) + " (fields: radius_m, height_m)");
    else if (r.has(k) && o.shape == Shape::Box && std::string(k) == "radius_m")
      r.fail(prefix + "radius_m is not a field of a box (fields: length_m, width_m, height_m)");
  o.texture = static_cast<Texture>(r.choice("texture", 1, kTextureNames));
  if (const toml::node* c = r.get("color")) {
    const toml::array* a = c->as_array();
    if (!a || a->size() != 3)
      r.fail(prefix + "color = " + node_text(*c) + " is not valid: expected [r, g, b], each an int in [0, 255]");
    for (std::size_t i = 0; i < 3; ++i) {
      const toml::node& e = *a->get(i);
      if (!e.is_integer() || e.as_integer()->get() < 0 || e.as_integer()->get() > 255)
        r.fail(prefix + "color[" + std::to_string(i) + "] = " + node_text(e) +
               " is out of range: int in [0, 255]");
      o.color[i] = static_cast<int>(e.as_integer()->get());
    }
  }
  o.vx_mps = r.num("vx_mps", 0.0, {-20.0, 20.0, false, false, "m/s"});
  o.vy_mps = r.num("vy_mps", 0.0, {-20.0, 20.0, false, false, "m/s"});
  if (const toml::node* tn = r.get("turns")) {  // [[t_s, vx_mps, vy_mps], ...], t non-decreasing, >= 0
    const std::string what = prefix + "turns";
    const toml::array* a = tn->as_array();
    if (!a) r.fail(what + " = " + node_text(*tn) + " is not valid: expected [[t_s, vx_mps, vy_mps], ...]");
    double last = 0.0;
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::array* e = a->get(i)->as_array();
      const std::string at = what + "[" + std::to_string(i) + "]";
      if (!e || e->size() != 3) r.fail(at + " is not valid: expected [t_s, vx_mps, vy_mps]");
      std::array<double, 3> k{};
      for (std::size_t c = 0; c < 3; ++c) {
        const toml::node& x = *e->get(c);
        if (!x.is_number()) r.fail(at + " = " + node_text(*e->get(c)) + " is not a number");
        k[c] = x.is_integer() ? static_cast<double>(x.as_integer()->get()) : x.as_floating_point()->get();
      }
      if (!std::isfinite(k[0]) || k[0] < last || k[0] > 1e6)
        r.fail(at + " time " + num_text(k[0]) + " is out of range: float in [" + num_text(last) + ", 1e6] s (non-decreasing)");
      if (!std::isfinite(k[1]) || !std::isfinite(k[2]) || std::fabs(k[1]) > 20.0 || std::fabs(k[2]) > 20.0)
        r.fail(at + " velocity is out of range: floats in [-20, 20] m/s");
      last = k[0];
      o.turns.push_back(k);
    }
  }
  r.finish();
  return o;
}

}  // namespace

const char* to_string(SkyKind k) { return kSkyNames[static_cast<std::size_t>(k)].c_str(); }
const char* to_string(GroundTexture t) { return kGroundNames[static_cast<std::size_t>(t)].c_str(); }
const char* to_string(Shape s) { return kShapeNames[static_cast<std::size_t>(s)].c_str(); }
const char* to_string(Texture t) { return kTextureNames[static_cast<std::size_t>(t)].c_str(); }
const std::vector<std::string>& sky_kind_names() { return kSkyNames; }
const std::vector<std::string>& ground_texture_names() { return kGroundNames; }
const std::vector<std::string>& shape_names() { return kShapeNames; }
const std::vector<std::string>& texture_names() { return kTextureNames; }

Scene parse_scene(const std::string& toml_text, const std::string& source) {
  toml::table root;
  try {
    root = toml::parse(toml_text, source);
  } catch (const toml::parse_error& e) {
    std::ostringstream ss;
    ss << source << ":" << e.source().begin.line << ":" << e.source().begin.column
       << ": TOML syntax error: " << e.description();
    throw ConfigError(ss.str());
  }
  Scene s;
  s.source = source;
  Reader top(&root, "", source);
  // Every non-negative TOML integer (int64): the generator's scene seeds use all 63 bits.
  s.seed = static_cast<std::uint64_t>(top.integer("seed", 0, {0.0, 9223372036854775807.0}));
  s.type = top.str("type", s.type);
  if (s.type.empty() || s.type.size() > 64) top.fail("type = \"" + s.type + "\" is not valid: 1 to 64 characters");

  {
    Reader r(top.table("camera"), "camera.", source);
    CameraSpec& c = s.camera;
    c.width = static_cast<int>(r.integer("width", c.width, {16, 4096, false, false, "px"}));
    c.height = static_cast<int>(r.integer("height", c.height, {16, 4096, false, false, "px"}));
    c.focal_px = r.num("focal_px", c.focal_px, {1.0, 20000.0, false, false, "px"});
    c.cx = r.num("cx", (c.width - 1) / 2.0, {0.0, static_cast<double>(c.width - 1), false, false, "px"});
    c.cy = r.num("cy", (c.height - 1) / 2.0, {0.0, static_cast<double>(c.height - 1), false, false, "px"});
    c.baseline_m = r.num("baseline_m", c.baseline_m, {0.0, 2.0, true, false, "m"});
    c.height_m = r.num("height_m", c.height_m, {0.05, 10.0, false, false, "m"});
    c.pitch_deg = r.num("pitch_deg", c.pitch_deg, {-30.0, 60.0, false, false, "deg"});
    r.finish();
  }
  {
    Reader r(top.table("robot"), "robot.", source);
    RobotSpec& b = s.robot;
    b.x_m = r.num("x_m", b.x_m, {-kBig, kBig, false, false, "m"});
    b.y_m = r.num("y_m", b.y_m, {-kBig, kBig, false, false, "m"});
    b.yaw_deg = r.num("yaw_deg", b.yaw_deg, {-360.0, 360.0, false, false, "deg"});
    b.radius_m = r.num("radius_m", b.radius_m, {0.0, 5.0, true, false, "m"});
    r.finish();
  }
  if (const toml::table* mt = top.table("mission")) {
    Reader r(mt, "mission.", source);
    MissionSpec m;
    m.goal_x_m = r.num("goal_x_m", m.goal_x_m, {-kBig, kBig, false, false, "m"});
    m.goal_y_m = r.num("goal_y_m", m.goal_y_m, {-kBig, kBig, false, false, "m"});
    m.time_limit_s = r.num("time_limit_s", m.time_limit_s, {0.0, 3600.0, true, false, "s"});
    r.finish();
    s.mission = m;
  }
  {
    Reader r(top.table("sky"), "sky.", source);
    s.sky.kind = static_cast<SkyKind>(r.choice("kind", 0, kSkyNames));
    r.finish();
  }
  {
    Reader r(top.table("light"), "light.", source);
    LightSpec& l = s.light;
    l.sun_azimuth_deg = r.num("sun_azimuth_deg", l.sun_azimuth_deg, {-360.0, 360.0, false, false, "deg"});
    l.sun_elevation_deg = r.num("sun_elevation_deg", l.sun_elevation_deg, {0.0, 90.0, false, false, "deg"});
    l.ambient = r.num("ambient", l.ambient, {0.0, 1.0});
    r.finish();
  }
  {
    Reader r(top.table("ground"), "ground.", source);
    s.ground.texture = static_cast<GroundTexture>(r.choice("texture", 0, kGroundNames));
    s.ground.scale_m = r.num("scale_m", s.ground.scale_m, {0.05, 20.0, false, false, "m"});
    r.finish();
  }
  {
    Reader r(top.table("radiometric"), "radiometric.", source);
    s.radiometric.left = read_radiometry(r, "left", source);
    s.radiometric.right = read_radiometry(r, "right", source);
    r.finish();
  }
  {
    Reader r(top.table("render"), "render.", source);
    s.render.supersample = static_cast<int>(r.integer("supersample", s.render.supersample, {1, 4}));
    s.render.far_m = r.num("far_m", s.render.far_m, {1.0, 1000.0, false, false, "m"});
    r.finish();
  }
  if (const toml::node* on = top.get("obstacles")) {
    const toml::array* arr = on->as_array();
    if (!arr || !arr->is_array_of_tables())
      top.fail("obstacles must be an array of tables [[obstacles]], not " + node_text(*on));
    std::map<int, int> used;  // id -> index
    for (std::size_t i = 0; i < arr->size(); ++i) {
      ObstacleSpec o = read_obstacle(arr->get(i)->as_table(), static_cast<int>(i), source);
      if (o.id >= 0) {
        if (const auto it = used.find(o.id); it != used.end())
          top.fail("obstacles[" + std::to_string(i) + "].id = " + std::to_string(o.id) + " is already used by obstacles[" +
                   std::to_string(it->second) + "]");
        used[o.id] = static_cast<int>(i);
      }
      s.obstacles.push_back(o);
    }
    // Missing ids: the smallest unused ids, in file order.
    int next = 0;
    for (auto& o : s.obstacles) {
      if (o.id >= 0) continue;
      while (used.count(next)) ++next;
      o.id = next;
      used[next] = -1;
    }
  }
  top.finish();
  return s;
}

Scene load_scene(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ConfigError("cannot read scene file '" + path + "': no such file or not readable");
  std::ostringstream ss;
  ss << f.rdbuf();
  return parse_scene(ss.str(), path);
}

std::string scene_to_toml(const Scene& s) {
  std::ostringstream o;
  auto n = [](double v) { return num_text(v); };
  o << "# fuzzystereo synthetic scene (docs/simulator.md)\n";
  o << "seed = " << s.seed << "\n";
  o << "type = \"" << s.type << "\"\n\n";
  const CameraSpec& c = s.camera;
  o << "[camera]\nwidth = " << c.width << "\nheight = " << c.height << "\nfocal_px = " << n(c.focal_px)
    << "\ncx = " << n(c.cx) << "\ncy = " << n(c.cy) << "\nbaseline_m = " << n(c.baseline_m)
    << "\nheight_m = " << n(c.height_m) << "\npitch_deg = " << n(c.pitch_deg) << "\n\n";
  o << "[robot]\nx_m = " << n(s.robot.x_m) << "\ny_m = " << n(s.robot.y_m) << "\nyaw_deg = " << n(s.robot.yaw_deg)
    << "\nradius_m = " << n(s.robot.radius_m) << "\n\n";
  if (s.mission)
    o << "[mission]\ngoal_x_m = " << n(s.mission->goal_x_m) << "\ngoal_y_m = " << n(s.mission->goal_y_m)
      << "\ntime_limit_s = " << n(s.mission->time_limit_s) << "\n\n";
  o << "[sky]\nkind = \"" << to_string(s.sky.kind) << "\"\n\n";
  o << "[light]\nsun_azimuth_deg = " << n(s.light.sun_azimuth_deg) << "\nsun_elevation_deg = "
    << n(s.light.sun_elevation_deg) << "\nambient = " << n(s.light.ambient) << "\n\n";
  o << "[ground]\ntexture = \"" << to_string(s.ground.texture) << "\"\nscale_m = " << n(s.ground.scale_m) << "\n\n";
  for (const auto& [name, r] : {std::pair{"left", &s.radiometric.left}, std::pair{"right", &s.radiometric.right}})
    o << "[radiometric." << name << "]\ngain = " << n(r->gain) << "\ngamma = " << n(r->gamma) << "\nbias = " << n(r->bias)
      << "\nnoise_sigma = " << n(r->noise_sigma) << "\n\n";
  o << "[render]\nsupersample = " << s.render.supersample << "\nfar_m = " << n(s.render.far_m) << "\n";
  for (const auto& b : s.obstacles) {
    o << "\n[[obstacles]]\nid = " << b.id << "\nshape = \"" << to_string(b.shape) << "\"\nx_m = " << n(b.x_m)
      << "\ny_m = " << n(b.y_m) << "\nz_m = " << n(b.z_m) << "\nyaw_deg = " << n(b.yaw_deg) << "\n";
    if (b.shape == Shape::Box)
      o << "length_m = " << n(b.length_m) << "\nwidth_m = " << n(b.width_m) << "\n";
    else
      o << "radius_m = " << n(b.radius_m) << "\n";
    o << "height_m = " << n(b.height_m) << "\ntexture = \"" << to_string(b.texture) << "\"\ncolor = [" << b.color[0]
      << ", " << b.color[1] << ", " << b.color[2] << "]\nvx_mps = " << n(b.vx_mps) << "\nvy_mps = " << n(b.vy_mps)
      << "\n";
    if (!b.turns.empty()) {
      o << "turns = [";
      for (std::size_t i = 0; i < b.turns.size(); ++i)
        o << (i ? ", " : "") << "[" << n(b.turns[i][0]) << ", " << n(b.turns[i][1]) << ", " << n(b.turns[i][2]) << "]";
      o << "]\n";
    }
  }
  return o.str();
}

}  // namespace fs::sim
