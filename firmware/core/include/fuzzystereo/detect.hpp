// Obstacle detection from a refined disparity map (paper Section III-B, eq. (16)-(25)):
//   road from the v-disparity image (eq. 16-17)  ->  sky from HSV colour (eq. 18-21)  ->
//   k-means on the remaining disparities (eq. 22-23)  ->  u-disparity filtering per cluster
//   (eq. 24-25)  ->  connected components  ->  distance Z = f*B/d and near/mid/far classes.
// Every choice the paper leaves open is written down, with its reason, in docs/detection.md.
//
// Formats: disparities are int16 Q4 (kDispShift, value = d*16, kInvalidDisp = no estimate) as in
// the matcher. Histograms (v- and u-disparity) are over the *integer* disparity
// round(d) = (q4 + kDispScale/2) >> kDispShift. Masks are uint8 0/1. k-means runs in integers on
// the Q4 values (centres are Q4). No floating point touches a per-pixel decision except the road
// line, which is turned into an integer Q4 table once per frame (road_line_q4).
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "fuzzystereo/calib.hpp"
#include "fuzzystereo/image.hpp"

namespace fs {

// One inclusive HSV box (H in degrees 0..359, S and V in 0..100 as in eq. (19)-(21)).
// h_min > h_max means the hue range wraps through 0 (e.g. 340..30 for red/orange).
struct HsvRange {
  bool enabled = true;
  int h_min = 0, h_max = 359;
  int s_min = 0, s_max = 100;
  int v_min = 0, v_max = 100;
};

enum class SkyLimit { Horizon, Fraction };
// Contained groups (measure_obstacles): where the larger group must have pixels around the smaller one.
// Off: box containment alone; Opposite: left and right (within its rows) or above and below (within its
// columns); All: on all four sides.
enum class ContainSurround { Off, Opposite, All };

// Defaults mirror the [detect] section of common/config/default.toml (ranges in schema.toml).
struct DetectParams {
  // ---- hole filling (our addition, before the road stage) ----
  int fill_max_run_px = 16;             // invalid runs along a row up to this length take the farther
                                       // bounding disparity (0 = off)
  bool fill_left_border = false;       // fill runs touching the left border too (the band the right
                                       // camera does not see); see fill_holes
  // ---- road, v-disparity (eq. 16-17) ----
  bool road_enabled = true;
  int road_min_cell_count = 3;         // v-disparity cells with fewer pixels are ignored by the fit
  int road_ransac_iterations = 300;    // weighted RANSAC samples (deterministic generator)
  int road_ransac_seed = 1;
  double road_fit_tolerance_px = 1.0;  // cell inlier band around the line [px of disparity]
  double road_slope_min = 0.02;        // accepted line slopes a [px of disparity per row]
  double road_slope_max = 2.0;
  double road_min_support_pct = 5.0;   // line accepted when inliers >= this % of valid pixels
  double road_tolerance_px = 1.0;      // pixel is road when |d - (a*v + b)| <= this [px]
  double road_tolerance_rel = 0.02;    // ... plus this share of the line's disparity a*v + b (0 = off)
  int road_close_radius = 4;           // closing with a (2r+1)^2 square; 0 = off [px]
  int road_fill_invalid_px = 128;      // after closing, a row run of invalid pixels up to this long between
                                       // road pixels (or road and the border) is road (0 = off) [px]
  // ---- sky, HSV (eq. 18-21) ----
  bool sky_enabled = true;
  SkyLimit sky_limit = SkyLimit::Horizon;
  double sky_upper_fraction = 0.5;     // rows above this fraction of the height (Fraction, or fallback)
  std::array<HsvRange, 3> sky_ranges{};  // blue sky, overcast/bright grey, sunset (docs/detection.md)
  double sky_max_disparity_px = 0.0;   // >0: a pixel with a valid disparity above this is never sky
  double sky_max_texture = 6.0;       // >0: a pixel whose grey-level std over the (2r+1)^2 window exceeds this is never
                                     // sky (session 8; grey levels 0..255; 0 = off; on since session 49,
                                     // docs/results-detection.md "Session 49")
  int sky_texture_radius = 2;        // ... r [px]
  // ---- k-means (eq. 22-23) ----
  int kmeans_k = 6;
  int kmeans_max_iterations = 30;
  double kmeans_min_disparity_px = 1.0;  // smaller (farther) disparities are not obstacle candidates
  double kmeans_merge_px = 1.0;    // after k-means, neighbouring centres closer than this merge (0 = off)
  // ---- u-disparity (eq. 24-25) ----
  int udisp_min_height_px = 8;     // cell kept when >= this many pixels of the column share its disparity
  int udisp_d_tolerance_px = 1;    // ... counting disparities within +-this many px (histogram box filter)
  int udisp_min_run_px = 6;        // and it lies in a horizontal run of kept cells at least this long
  // ---- components and distance ----
  double cc_max_step_px = 1.0;     // 8-neighbours join when their disparities differ by <= this [px]
  double cc_max_rel_step = 0.05;   // ... and by <= this share of the larger disparity (0 = off)
  double cc_min_step_px = 0.25;    // ... the relative limit never goes below this [px]
  int merge_gap_px = 8;           // components whose boxes grown by this overlap ... (-1 = no merging)
  int merge_gap_vertical_px = 16;  // ... in y: the vertical growth, max(this, merge_gap_px) (tall obstacles cut in height)
  double merge_max_rel_disparity = 0.1;  // ... and whose medians differ <= this share of the larger merge
  double merge_group_max_rel = 0.0;   // complete linkage: a merged group's member medians span <= this share of the
                                   // largest (session 8; 0 = single linkage, no group limit: the default,
                                   // see docs/results-detection.md "Session 8" for the trade-off)
  bool merge_attach = true;        // with complete linkage: each group then joins the touching larger group of
                                   // nearest median within merge_max_rel_disparity (one step, no chains)
  int merge_bridge_max_px = 500;     // single linkage: components with fewer pixels than this join at most one
                                   // group of larger ones (no chains through small fragments; session 10, 0 = off)
  double merge_bridge_max_overlap = 0.5;  // ... refused only between large ones side by side: column overlap <= this
                                         // share of the narrower box
  int merge_occluded_max_gap_px = 200;  // same-depth components on both sides of nearer ones merge across
                                      // a gap up to this wide (0 = off)
  double split_min_rel = 0.12;     // split a component whose disparity histogram has two modes this far apart
                                   // (share of the larger lower median; 0 = off)
  double split_max_valley = 0.1;   // ... when at most this share of its pixels lies between the modes
  int split_min_px = 100;          // ... and each side has at least this many pixels
  int split_rounds = 2;            // splitting passes (a component over three depths needs two)
  int neck_min_width_px = 12;      // cut a component at a run of at least this many thin columns (0 = off)
  double neck_max_share = 0.3;     // ... a column is thin when it holds <= this share of the component's
                                   // 75th-percentile column count
  int neck_min_px = 100;           // ... and each side of the cut keeps at least this many pixels
  double neck_foot_share = 0.0;    // ... and (> 0) the thin columns' pixels all lie in this lowest share of
                                   // the box rows (a strip at the feet); 0 = at any height
  double seam_min_step = 0.08;      // cut an obstacle where the mean chromaticity of its columns changes by at
                                   // least this (max over r, g, b of c / (r + g + b), regularised) between the
                                   // seam_window columns on each side (two touching obstacles; session 33; 0 = off)
  int seam_window_px = 8;          // ... columns compared on each side of a seam [px]
  int seam_min_width_px = 14;      // ... each side of a cut keeps at least this many columns [px]
  int seam_min_px = 300;           // ... and at least this many pixels
  int seam_max_cuts = 2;           // ... at most this many cuts per obstacle
  double seam_min_rows = 0.7;      // ... and at least this share of its rows agree with the cut (0 = no row test)
  double seam_drop_share = 0.0;    // a cut piece with fewer than this share of the obstacle's pixels is dropped
                                   // (background the matcher attached to its side; 0 = every piece kept)
  double merge_edge_rel_disparity = 0.05;  // side-by-side groups whose facing edges' disparities differ <= this
                                       // share join (a slanted surface cut by k-means; 0 = off)
  int merge_edge_columns = 4;      // ... the edge = this many outermost columns of each group [px]
  double contain_min_inside = 0.6; // a group whose box lies this share inside a larger group's box (0 = off) ...
  double contain_merge_rel_disparity = 0.12; // ... joins it when the medians differ <= this share of the larger
  int contain_drop_max_px = 300;   // ... otherwise is dropped when smaller than this (0 = never dropped)
  bool contain_drop_nearer_only = false;  // ... and only when nearer than the containing group
  ContainSurround contain_surround = ContainSurround::Opposite;  // where the larger group must have pixels
  double max_distance_m = 20.0;    // obstacles farther than this are dropped (0 = off) [m]
  // ---- box extent (session 5 round 3) ----
  bool foot_extend = true;         // a box whose bottom touches the road band of its disparity ends where
                                   // the road line reaches that disparity (the row above) (the foot rows the band removed)
  double foot_slack_px = 2.0;      // ... the bottom may lie this much disparity above the band [px]
  double trim_col_min_share = 0.1; // side columns with fewer pixels than this share of the fullest column are
                                   // cut off the box (0 = off)
  double trim_col_top_share = 0.5; // ... and side columns whose highest pixel (or sky-masked pixel at the
                                   // obstacle's depth) lies lower than this share of the box height (0 = off)
  bool foot_gap_extend = false;    // a box whose bottom lies above its foot row (the road line reaches its
                                   // disparity lower down) ends at the foot row when the gap between holds few
                                   // pixels of nearer obstacles (session 14; the lower part the matcher lost)
  double foot_gap_max_occluded = 0.3;  // ... at most this share of the gap (rows below the box to the foot,
                                   // the box's columns) belongs to obstacles nearer by > merge_max_rel_disparity
  // ---- plausibility (session 7, docs/detection.md "(a) Slope prior", "(e) Below the road") ----
  double road_slope_prior_rel = 0.5;  // with a known mounting (calib height_m > 0) the road line's slope must lie
                                   // within a factor 1 + this of B*cos(pitch)/h (0 = off; see road_slope_range)
  double seen_through_drop_share = 0.0;  // obstacles with at least this share of their pixels in columns where one
                                   // nearer obstacle lies above and below them are dropped (session 8; 0 = off,
                                   // the default: 0.5 cost closed-loop safe stops, docs/results-detection.md)
  double below_road_drop_share = 0.5;  // obstacles with at least this share of their pixels below the road at
                                   // their own depth (beyond the road band) are dropped (0 = off)
  double inside_drop_min_share = 0.85;  // a farther obstacle whose box lies at least this share inside the box of a
                                   // larger obstacle nearer by > merge_max_rel_disparity ... (session 14; 0 = off;
                                   // 0.85 since session 49)
  double inside_drop_min_ring = 0.25;  // ... and whose surrounding band holds at least this share of the nearer
                                   // one's pixels is dropped (a blob of background disparity in its face)
  int inside_drop_ring_px = 6;     // ... the band: this many pixels around the farther obstacle's box [px]
  double side_face_max_rel = 0.35;  // a narrow obstacle beside a larger one and at most this share farther (Z ratio - 1)
                                   // is its side face: it joins it (session 33; 0 = off)
  double side_face_max_width = 0.2;  // ... narrow: its box at most this share of the larger one's width
  double side_face_min_rows = 0.8;   // ... at least this share of its box rows lie within the larger one's rows
  int side_face_max_gap_px = 2;    // ... and the boxes touch: at most this many columns apart (overlaps allowed, its
                                   // centre column outside the larger box) [px]
  int min_area_px = 200;           // smaller components are dropped
  double min_area_m2 = 0.025;      // obstacles whose pixels cover less than this (pixels * (Z/f)^2) are dropped (0 = off)
  double min_height_m = 0.15;       // obstacles lower than this (box rows * Z / f) are dropped (0 = off)
  double near_m = 2.0;             // Z < near_m: near (red)
  double far_m = 5.0;              // Z >= far_m: far (blue); otherwise mid (green)

  DetectParams();
};

enum class ObstacleClass : int { Near = 0, Mid = 1, Far = 2 };
const char* obstacle_class_name(ObstacleClass c);

struct Obstacle {
  int id = 0;                       // 0.. in order of distance (nearest first)
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // inclusive box of the obstacle's pixels; y1 may extend below
                                    // them to the ground contact (extend_to_ground) [px]
  int pixel_count = 0;
  int disparity_q4 = 0;             // median Q4 disparity of the component
  double distance_m = 0.0;          // Z = f*B/d [m]
  double lateral_m = 0.0;           // X of the box centre column [m], + = right
  ObstacleClass cls = ObstacleClass::Mid;
};

// Road line d = a*v + b in the v-disparity image (v = image row, d in px).
struct RoadLine {
  bool found = false;
  double a = 0.0, b = 0.0;
  int horizon_row = -1;        // first row with a*v + b > 0 (rows >= it are road candidates); -1 = none
  std::int64_t support = 0;    // pixels (cell weights) within the fit tolerance
};

enum class DetectStage : int { Road, Sky, KMeans, UDisparity, Objects, Count };
const char* detect_stage_name(DetectStage s);

struct DetectTimings {
  std::array<double, static_cast<int>(DetectStage::Count)> ms{};
  double total_ms() const;
};

struct DetectResult {
  ImageI16 disp;                // the disparity every stage used: the input after hole filling (Q4)
  int bins = 0;                 // integer disparities 0 .. bins-1 in the histograms
  ImageI32 vdisp;               // width = bins, height = rows: eq. (17)
  RoadLine road;
  std::vector<std::int32_t> road_line_q4;  // per row: expected Q4 disparity (INT32_MIN above horizon)
  ImageU8 road_raw;             // 1 = on the line (before closing)
  ImageU8 road_mask;            // 1 = road (after closing and invalid-run completion)
  bool sky_skipped = true;      // no colour image (mono camera) or sky_enabled = false
  int sky_rows = 0;             // rows 0 .. sky_rows-1 were searched
  ImageU8 sky_mask;             // 1 = sky
  ImageU8 candidates;           // 1 = valid, not road, not sky, disparity >= kmeans_min_disparity
  std::vector<std::int32_t> centres_q4;  // cluster centres, nearest (largest disparity) first
  std::vector<std::int64_t> cluster_sizes;
  int kmeans_iterations = 0;
  ImageU8 cluster_labels;       // cluster index, kNoCluster = not a candidate
  std::vector<ImageU8> udisp_kept;  // per cluster: width = image width, height = bins; 1 = kept cell
  ImageU8 kept;                 // 1 = pixel survived the u-disparity filter
  ImageI32 components;          // 0 = none, 1.. = component (raster order of first pixel), before min-area
  std::vector<Obstacle> obstacles;
  ImageI32 obstacle_labels;     // 0 = none, id + 1 (same convention as the simulator's GT)
  DetectTimings timings;
};

inline constexpr std::uint8_t kNoCluster = 255;
inline constexpr int kMaxClusters = 16;

// ---- stages (free functions, one file each in firmware/core/src/detect/) -----------------------
namespace detect {

// Row-wise background interpolation: invalid runs of <= max_run pixels take min(left, right)
// bounding disparity (the one neighbour at the image border); 0 = copy unchanged.
ImageI16 fill_holes(const ImageI16& disp, int max_run, bool left_border = true);

// round(d) of a valid Q4 disparity.
inline int disp_bin(std::int16_t q4) { return (q4 + kDispScale / 2) >> kDispShift; }
// Number of histogram bins needed for `disp` (largest rounded disparity + 1, at least 1).
int disparity_bins(const ImageI16& disp);

// eq. (16)-(17): vdisp(v, d) = number of pixels of row v whose rounded disparity is d.
ImageI32 v_disparity(const ImageI16& disp, int bins);
// Weighted RANSAC + weighted least-squares refit of the road line in the v-disparity image.
RoadLine fit_road_line(const ImageI32& vdisp, std::int64_t valid_pixels, const DetectParams& p);
// Road slope range (docs/detection.md "(a) Slope prior"): [road_slope_min, road_slope_max], narrowed with a
// known mounting (calib.height_m > 0, road_slope_prior_rel > 0) to [a0 / (1 + r), a0 * (1 + r)], a0 = B cos(pitch)
// / h: the slope of a flat road's v-disparity line, d = (B / h) ((v - cy) cos(pitch) + f sin(pitch)). Returns
// false when the two ranges do not overlap (no line can be accepted).
bool road_slope_range(const DetectParams& p, const StereoCalib& calib, double* lo, double* hi);
// Per row, the line's disparity in Q4 (rows above the horizon: INT32_MIN).
std::vector<std::int32_t> road_line_table(const RoadLine& line, int rows);
// 1 where the pixel is valid and |q4 - line_q4[v]| <= tol_q4(v) (rows below the horizon), with
// tol_q4(v) = round(tolerance_px * 16 + tolerance_rel * line_q4[v]) (band widening with disparity).
ImageU8 road_pixels(const ImageI16& disp, const std::vector<std::int32_t>& line_q4, double tolerance_px,
                    double tolerance_rel = 0.0);
// Binary closing (dilate then erode) with a (2r+1)^2 square; outside the image counts as 0 for the
// dilation and 1 for the erosion, so the closing never eats the border.
ImageU8 close_mask(const ImageU8& mask, int radius);
// Road completion (docs/detection.md "(a)"): in rows with a line value, each run of invalid pixels
// (disp < 0) of at most max_run pixels whose bounding pixels are both road (one bounding pixel at the
// image border) becomes road. Only invalid pixels change, so the obstacle candidates do not. 0 = copy.
ImageU8 complete_road(const ImageU8& road, const ImageI16& disp, const std::vector<std::int32_t>& line_q4, int max_run);

// eq. (18)-(21) in integers: H in degrees 0..359, S and V in 0..100, each rounded to nearest.
struct Hsv {
  int h = 0, s = 0, v = 0;
};
Hsv rgb_to_hsv(Rgb8 c);
bool in_range(const Hsv& c, const HsvRange& r);
// 1 for rows < rows_limit whose colour lies in an enabled range (and, when
// p.sky_max_disparity_px > 0, whose disparity is invalid or not above it).
// 1 for rows < rows_limit where every pixel of the (2r+1)^2 window (within the image and those rows) has a
// grey-level (luma) standard deviation over its own (2r+1)^2 window (clipped at the border) above max_std:
// the std test, then an erosion by the same window (docs/detection.md "(b) Texture"); all 0 when
// max_std <= 0 or radius < 1.
ImageU8 textured_mask(const ImageRgb8& rgb, int rows_limit, int radius, double max_std);
ImageU8 sky_mask(const ImageRgb8& rgb, const ImageI16& disp, int rows_limit, const DetectParams& p);

struct KMeansResult {
  std::vector<std::int32_t> centres_q4;  // nearest first
  std::vector<std::int64_t> sizes;
  int iterations = 0;
  ImageU8 labels;  // kNoCluster where candidates == 0
};
// eq. (22)-(23), 1-D on the Q4 disparities of candidate pixels, via a histogram over Q4 values;
// then clusters whose centres are closer than merge_q4 to their neighbour merge (single linkage
// along the sorted centres; merged centre = rounded weighted mean). merge_q4 = 0 keeps all k.
KMeansResult kmeans_disparity(const ImageI16& disp, const ImageU8& candidates, int k, int max_iterations,
                              int merge_q4 = 0);

// eq. (24)-(25) per cluster, cell filter and horizontal runs; returns per-cluster kept cells and
// the kept pixels.
struct UDispResult {
  std::vector<ImageU8> kept_cells;
  ImageU8 kept;
};
// Reusable buffers of the u-disparity stage (the clusters' histograms: clusters * bins * width int32).
struct UDispScratch {
  std::vector<std::int32_t> hist, support;
};
UDispResult u_disparity_filter(const ImageI16& disp, const ImageU8& labels, int clusters, int bins,
                               const DetectParams& p, UDispScratch* scratch = nullptr);

// 8-connected components of mask==1 whose neighbouring Q4 disparities differ by <= max_step_q4.
// Two-pass union-find; labels 1.. numbered in raster order of each component's first pixel.
// rel_step > 0: a step must also be <= max(min_step_q4, rel_step * the larger of the two disparities).
ImageI32 connected_components(const ImageU8& mask, const ImageI16& disp, int max_step_q4, int* count,
                              double rel_step = 0.0, int min_step_q4 = 0);

// Splitting bimodal components (docs/detection.md "(e)"). bimodal_threshold_q4: hist[i] counts Q4
// value lo + i; returns Otsu's threshold t (class 0: q4 < t) when both classes have >= min_px pixels,
// their lower medians m0 < m1 satisfy m1 - m0 >= min_rel * m1 and [m0 + (m1-m0)/4, m1 - (m1-m0)/4]
// holds <= max_valley of all pixels; otherwise -1.
int bimodal_threshold_q4(const std::vector<std::int32_t>& hist, int lo, int min_px, double min_rel, double max_valley);
// Each component with a threshold is cut in two by it and relabelled (8-neighbours join when they had
// the same label and lie on the same side); `rounds` passes; labels renumbered in raster order of
// first appearance. min_rel <= 0 or rounds <= 0: unchanged.
ImageI32 split_bimodal_components(const ImageI32& components, int count, const ImageI16& disp, int min_px,
                                  double min_rel, double max_valley, int rounds, int* out_count);
// Necks (docs/detection.md "(e) Necks", session 30): per component, the pixel count of each column of
// its box; a run of >= min_width consecutive columns each holding <= max_share of the component's
// 75th-percentile column count, with >= min_px pixels and a column above that share on each side, is
// a neck (two obstacles joined through a thin strip, e.g. the road at their feet that the matcher gave
// their disparity). The neck's pixels are dropped; each part of a cut label between necks becomes one
// label (its pixels need not be connected), other labels are kept whole; labels renumbered in raster
// order of first appearance. min_width <= 0 or no neck: unchanged (and *out_count = count).
// foot_share > 0: only thin runs whose every column's topmost pixel lies in the lowest foot_share of the
// component's box rows (a strip at the feet).
ImageI32 split_necks(const ImageI32& components, int count, int min_width, double max_share, int min_px,
                     double foot_share, int* out_count);
// Seams (docs/detection.md "(e) Seams", session 33): two obstacles side by side at nearly one depth,
// which no disparity rule separates, usually differ in colour. Per label, the pixel sums of R, G, B of
// each column of its box; at a boundary between columns, the chromaticity of the label's pixels in the
// `window` columns on each side, c = (sum C + 10 n) / (sum R + sum G + sum B + 30 n) for C in R, G, B
// (Q16, integer; the 10 grey levels per pixel keep dark pixels' chromaticity from swinging), and the
// step = the largest |c_left - c_right| of the three. The boundary of the largest step, when it is
// >= min_step, leaves >= min_width columns and >= min_px pixels on each side and passes the row test,
// cuts the label there (candidates are tried strongest first);
// each side is searched again, up to max_cuts cuts per label. Row test (min_rows > 0): of the
// label's rows with pixels within 3 columns on both sides of the boundary, at least the share min_rows
// have their left pixels' chromaticity nearer the left window's than the right's and their right
// pixels' nearer the right window's (a seam runs down the whole box; blobs of one camouflaged
// surface do not). drop_share > 0: a piece with fewer than that share of its label's pixels is dropped
// (a sliver of background attached to the obstacle's side by the matcher). Every cut part becomes one label (its
// pixels need not be connected), other labels are kept whole; labels renumbered in raster order of
// first appearance. min_step <= 0, an empty rgb or no cut: unchanged (and *out_count = count).
ImageI32 split_seams(const ImageI32& labels, int count, const ImageRgb8& rgb, double min_step, int window,
                     int min_width, int min_px, int max_cuts, double min_rows, double drop_share, int* out_count);

// Box, size, median disparity, Z, X and class per component (components >= min area), nearest
// first; fills `labels` (0 none, id+1).
std::vector<Obstacle> measure_obstacles(const ImageI32& components, int count, const ImageI16& disp,
                                        const StereoCalib& calib, const DetectParams& p, ImageI32* labels);
ObstacleClass classify_distance(double z_m, const DetectParams& p);

// Box extent (docs/detection.md "(e) Box extent"). Ground contact: an obstacle whose box bottom row is
// followed by a row whose road line value lies within the road band (road_tolerance_px,
// road_tolerance_rel; plus foot_slack_px) below its median disparity gets y1 = the first row where the
// line reaches that disparity (the last image row if it never does). line_q4 as road_line_table.
void extend_to_ground(std::vector<Obstacle>& obstacles, const std::vector<std::int32_t>& line_q4,
                      const DetectParams& p);
// Ground contact over a gap (docs/detection.md "(e) Box extent", session 14): an obstacle of median disparity d
// whose box ends above its foot row (the last row from its bottom on whose line value is below d; the last
// image row when the line stays below d) ends at the foot row when, in the rectangle of the box's columns and
// the rows below the box down to the foot row, at most foot_gap_max_occluded of the pixels carry the label
// (labels == id + 1) of an obstacle nearer by more than merge_max_rel_disparity (median Q4 > d * (1 + rel)).
// Only y1 changes. foot_gap_extend = false or no line: unchanged.
void extend_over_gap(std::vector<Obstacle>& obstacles, const ImageI32& labels, const std::vector<std::int32_t>& line_q4,
                     const DetectParams& p);
// Sparse and low sides: per obstacle, the box's outermost columns holding fewer of its pixels (labels ==
// id + 1) than trim_col_min_share of its fullest column, or whose top — highest own pixel, or sky pixel
// (sky != 0) whose disparity is within max(cc_min_step_px, cc_max_rel_step * d) of the obstacle's — lies
// below y0 + trim_col_top_share * box height, are cut (from the left and from the right, until a column
// passes); the cut pixels leave `labels`, and box rows, pixel_count and lateral_m are recomputed
// (distance unchanged). Both shares <= 0: unchanged. sky/disp may be null (no sky pixels count).
void trim_sparse_columns(std::vector<Obstacle>& obstacles, ImageI32& labels, const StereoCalib& calib,
                         const DetectParams& p, const ImageU8* sky = nullptr, const ImageI16* disp = nullptr);

// Below the road (docs/detection.md "(e) Below the road"): a pixel of an obstacle of median disparity d lies
// below the road at its own depth when its row's line value exceeds d by more than the road band there
// (line_q4[v] - d > round(16 * road_tolerance_px + road_tolerance_rel * line_q4[v])): nothing standing on a
// flat road at that depth can be seen there. Obstacles with >= below_road_drop_share of their pixels
// (labels == id + 1) so are dropped; the rest keep their order and are renumbered (ids, labels).
// below_road_drop_share <= 0 or no line: unchanged.
void drop_below_road(std::vector<Obstacle>& obstacles, ImageI32& labels, const std::vector<std::int32_t>& line_q4,
                     const DetectParams& p);

// Seen through (docs/detection.md "(e) Seen through", session 8): an obstacle F is dropped when, for one nearer
// obstacle H (median Q4 disparity > F's * (1 + merge_max_rel_disparity)), the columns where H has pixels
// above F's highest and below F's lowest pixel of that column hold >= seen_through_drop_share of F's pixels
// (labels == id + 1); the rest keep their order and are renumbered (ids, labels). Share <= 0: unchanged.
void drop_seen_through(std::vector<Obstacle>& obstacles, ImageI32& labels, const DetectParams& p);

// Inside a nearer face (docs/detection.md "(e) Inside a nearer face", session 14): an obstacle F is dropped when
// one obstacle H with more pixels and median Q4 > F's * (1 + merge_max_rel_disparity) has a box holding >=
// inside_drop_min_share of F's box area, and the band of inside_drop_ring_px pixels around F's box (clipped to
// the image) holds >= inside_drop_min_ring of H's pixels (labels == H.id + 1). Decided on the obstacles as they
// are (no chains); the rest keep their order and are renumbered (ids, labels). Share <= 0: unchanged.
void drop_inside_nearer(std::vector<Obstacle>& obstacles, ImageI32& labels, const DetectParams& p);

// Side faces (docs/detection.md "(e) Side faces", session 33): a box seen at an angle shows its front face and a
// receding side face; the side face, farther and split off by depth, is a narrow obstacle F beside the front
// face H. F joins H when H has more pixels, F is farther by at most side_face_max_rel (Z_F / Z_H - 1 in
// (0, rel], from the median Q4 disparities), F's box is at most side_face_max_width of H's width, >=
// side_face_min_rows of F's box rows lie within H's rows, the boxes are at most side_face_max_gap_px columns
// apart (or overlap) and F's centre column lies outside H's box. H (the largest such host) takes the union of
// the boxes and F's pixels (labels), keeps its distance (the nearer face); decided on the obstacles as they are
// (no chains); the rest are renumbered (ids, labels). side_face_max_rel <= 0: unchanged.
void merge_side_faces(std::vector<Obstacle>& obstacles, ImageI32& labels, const DetectParams& p);

}  // namespace detect

// Chains the stages, one line each. Keeps the u-disparity histograms between frames (the one large
// per-frame allocation); detect() holds a mutex, so one Detector serves one stream at a time.
class Detector {
 public:
  explicit Detector(const DetectParams& params);
  ~Detector();
  // disp: refined left disparity (Q4). rgb: left colour image of the same size, or empty for a mono
  // camera (the sky stage is skipped). calib: focal_px and baseline_m must be > 0 (checked by the
  // caller when loading the calibration).
  DetectResult detect(const ImageI16& disp, const ImageRgb8& rgb, const StereoCalib& calib) const;
  const DetectParams& params() const { return params_; }

 private:
  DetectParams params_;
  mutable std::mutex scratch_mu_;
  std::unique_ptr<detect::UDispScratch> scratch_;
};

}  // namespace fs
