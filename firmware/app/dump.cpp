// The stage dump (docs/formats.md) that `fuzzystereo match --dump` writes and the link snapshot
// sends; fuzzyctl compare reads it.
#include "dump.hpp"

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "config.hpp"
#include "io.hpp"

namespace fs::app {

void write_match_dump(const std::string& dir, const std::string& left_name, const std::string& right_name,
                      const MatcherParams& params, const FisDefinition& fis, const ImageU8& left, const ImageU8& right,
                      const MatchResult& r) {
  make_output_dir(dir);
  const std::size_t h = std::size_t(left.height), w = std::size_t(left.width);
  write_image(dir + "/left.png", to_mat(left));
  write_image(dir + "/right.png", to_mat(right));
  write_npy(dir + "/labels_left.npy", r.seg_left.labels.data.data(), {h, w});
  write_npy(dir + "/labels_right.npy", r.seg_right.labels.data.data(), {h, w});
  auto seg_table = [](const SegmentDecision& d) {
    std::vector<std::int32_t> t;
    for (std::size_t s = 0; s < d.disparity.size(); ++s) {
      t.push_back(d.disparity[s]);
      t.push_back(static_cast<std::int32_t>(d.score[s]));
      t.push_back(static_cast<std::int32_t>(d.dc1[s]));
      t.push_back(static_cast<std::int32_t>(d.dc2[s]));
      t.push_back(d.disparity_q4[s]);
    }
    return t;
  };
  const auto tl = seg_table(r.dec_left), tr = seg_table(r.dec_right);
  write_npy(dir + "/seg_left.npy", tl.data(), {r.dec_left.disparity.size(), 5});
  write_npy(dir + "/seg_right.npy", tr.data(), {r.dec_right.disparity.size(), 5});
  write_npy(dir + "/disp_left_wta.npy", r.disp_left_wta.data.data(), {h, w});
  write_npy(dir + "/disp_right_wta.npy", r.disp_right_wta.data.data(), {h, w});
  write_npy(dir + "/lr_mask.npy", r.lr_mask.data.data(), {h, w});
  write_npy(dir + "/disp_lr.npy", r.disp_lr.data.data(), {h, w});
  write_npy(dir + "/esr_replaced.npy", r.esr_replaced.data.data(), {h, w});
  write_npy(dir + "/disp_esr.npy", r.disp_esr.data.data(), {h, w});
  write_npy(dir + "/densify_changed.npy", r.densify_changed.data.data(), {h, w});
  write_npy(dir + "/disp_final.npy", r.disp_final.data.data(), {h, w});
  nlohmann::json meta;
  meta["format"] = "fuzzystereo-dump";
  meta["version"] = 1;
  meta["firmware_version"] = FS_VERSION;
  meta["width"] = w;
  meta["height"] = h;
  meta["left"] = left_name;
  meta["right"] = right_name;
  meta["config_toml"] = config_to_toml(params);
  meta["fis_name"] = fis.name;
  nlohmann::json t;
  for (int i = 0; i < static_cast<int>(Stage::Count); ++i) t[stage_name(Stage(i))] = r.timings.ms[std::size_t(i)];
  meta["timings_ms"] = t;
  // The radiometric decisions (docs/algorithm.md 2b, 2c).
  meta["radiometric"] = {{"grey_quantile_shift", r.grey_quantile_shift},
                         {"gradient_gain", r.gradient_gain_q16 / 65536.0},
                         {"noise_sigma_left", r.noise_sigma_left},
                         {"noise_sigma_right", r.noise_sigma_right},
                         {"noise_excess", r.noise_excess},
                         {"noise_equalised", r.noise_equalised},
                         {"gain_triggered", r.gain_triggered},
                         {"boundary_refined", r.boundary_refined}};
  meta["lr_check"] = {{"retry_recovered", r.retry_recovered}};  // docs/algorithm.md 5b
  std::ofstream f(dir + "/meta.json");
  f << meta.dump(2) << "\n";
  if (!f) throw UserError("cannot write '" + dir + "/meta.json'");
}

}  // namespace fs::app
