#include "grid.hpp"

#include <algorithm>
#include <limits>
#include <queue>

namespace fs::robot::detail {

void Grid::init(Vec2 lo, Vec2 hi, double resolution, int max_cells_per_axis) {
  const double ext = std::max(hi.x - lo.x, hi.y - lo.y);
  res = std::max(resolution, ext / max_cells_per_axis);
  origin = lo;
  nx = static_cast<int>(std::ceil((hi.x - lo.x) / res)) + 1;
  ny = static_cast<int>(std::ceil((hi.y - lo.y) / res)) + 1;
  blocked.assign(static_cast<std::size_t>(nx) * ny, 0);
}

namespace {
template <class F>
void for_disc(const Grid& g, Vec2 c, double r, F&& f) {
  const int x0 = std::max(0, static_cast<int>(std::floor((c.x - r - g.origin.x) / g.res)));
  const int x1 = std::min(g.nx - 1, static_cast<int>(std::ceil((c.x + r - g.origin.x) / g.res)));
  const int y0 = std::max(0, static_cast<int>(std::floor((c.y - r - g.origin.y) / g.res)));
  const int y1 = std::min(g.ny - 1, static_cast<int>(std::ceil((c.y + r - g.origin.y) / g.res)));
  const double r2 = r * r;
  for (int iy = y0; iy <= y1; ++iy)
    for (int ix = x0; ix <= x1; ++ix) {
      const Vec2 p = g.center(ix, iy);
      const double dx = p.x - c.x, dy = p.y - c.y;
      if (dx * dx + dy * dy <= r2) f(g.idx(ix, iy));
    }
}
}  // namespace

void Grid::fill_disc(Vec2 c, double r) {
  for_disc(*this, c, r, [&](int i) { blocked[i] = 1; });
}
void Grid::clear_disc(Vec2 c, double r) {
  for_disc(*this, c, r, [&](int i) { blocked[i] = 0; });
}

bool Grid::segment_free(Vec2 a, Vec2 b) const {
  const double len = norm(b - a);
  const int n = std::max(1, static_cast<int>(std::ceil(len / (0.5 * res))));
  for (int k = 0; k <= n; ++k) {
    const double t = static_cast<double>(k) / n;
    if (blocked_at(a + t * (b - a))) return false;
  }
  return true;
}

namespace {
constexpr int kDx[8] = {1, -1, 0, 0, 1, 1, -1, -1};
constexpr int kDy[8] = {0, 0, 1, -1, 1, -1, 1, -1};
constexpr double kSqrt2 = 1.4142135623730951;

double octile(int dx, int dy) {
  dx = std::abs(dx);
  dy = std::abs(dy);
  return (std::max(dx, dy) - std::min(dx, dy)) + kSqrt2 * std::min(dx, dy);
}

struct Node {
  double f;
  int i;
  bool operator>(const Node& o) const { return f > o.f; }
};
}  // namespace

bool in_small_pocket(const Grid& g, Vec2 p, int budget) {
  int px, py;
  g.cell_of(p, px, py);
  if (!g.inside(px, py) || g.blocked[g.idx(px, py)]) return false;
  std::vector<std::uint8_t> seen(g.blocked.size(), 0);
  std::vector<int> stack{g.idx(px, py)};
  seen[stack[0]] = 1;
  int count = 0;
  while (!stack.empty()) {
    const int cur = stack.back();
    stack.pop_back();
    if (++count > budget) return false;
    const int cx = cur % g.nx, cy = cur / g.nx;
    for (int k = 0; k < 8; ++k) {
      const int x = cx + kDx[k], y = cy + kDy[k];
      if (!g.inside(x, y)) continue;
      const int ni = g.idx(x, y);
      if (seen[ni] || g.blocked[ni]) continue;
      if (k >= 4 && (g.blocked[g.idx(cx + kDx[k], cy)] || g.blocked[g.idx(cx, cy + kDy[k])])) continue;
      seen[ni] = 1;
      stack.push_back(ni);
    }
  }
  return true;
}

std::vector<Vec2> astar(const Grid& g, Vec2 start, Vec2 goal) {
  int sx, sy, gx, gy;
  g.cell_of(start, sx, sy);
  g.cell_of(goal, gx, gy);
  if (!g.inside(sx, sy) || !g.inside(gx, gy) || g.blocked[g.idx(gx, gy)] || g.blocked[g.idx(sx, sy)]) return {};
  const int n = g.nx * g.ny;
  std::vector<float> gc(n, std::numeric_limits<float>::infinity());
  std::vector<int> parent(n, -1);
  std::vector<std::uint8_t> closed(n, 0);
  std::priority_queue<Node, std::vector<Node>, std::greater<Node>> open;
  const int s = g.idx(sx, sy), t = g.idx(gx, gy);
  gc[s] = 0;
  open.push({octile(gx - sx, gy - sy), s});
  while (!open.empty()) {
    const int cur = open.top().i;
    open.pop();
    if (closed[cur]) continue;
    closed[cur] = 1;
    if (cur == t) break;
    const int cx = cur % g.nx, cy = cur / g.nx;
    for (int k = 0; k < 8; ++k) {
      const int x = cx + kDx[k], y = cy + kDy[k];
      if (!g.inside(x, y)) continue;
      const int ni = g.idx(x, y);
      if (g.blocked[ni] || closed[ni]) continue;
      // no corner cutting between two blocked orthogonal neighbours
      if (k >= 4 && (g.blocked[g.idx(cx + kDx[k], cy)] || g.blocked[g.idx(cx, cy + kDy[k])])) continue;
      const float ng = gc[cur] + static_cast<float>(k < 4 ? 1.0 : kSqrt2);
      if (ng < gc[ni]) {
        gc[ni] = ng;
        parent[ni] = cur;
        open.push({ng + octile(gx - x, gy - y), ni});
      }
    }
  }
  if (!closed[t]) return {};
  std::vector<Vec2> path;
  for (int c = t; c != -1; c = parent[c]) path.push_back(g.center(c % g.nx, c / g.nx));
  std::reverse(path.begin(), path.end());
  path.front() = start;
  path.back() = goal;
  return path;
}

double theta_star_length(const Grid& g, Vec2 start, Vec2 goal, const std::function<bool(Vec2, Vec2)>& los) {
  if (los(start, goal)) return norm(goal - start);
  int sx, sy, gx, gy;
  g.cell_of(start, sx, sy);
  g.cell_of(goal, gx, gy);
  if (!g.inside(sx, sy) || !g.inside(gx, gy)) return std::numeric_limits<double>::infinity();
  const int n = g.nx * g.ny;
  const int s = g.idx(sx, sy), t = g.idx(gx, gy);
  auto pos = [&](int i) { return i == s ? start : (i == t ? goal : g.center(i % g.nx, i / g.nx)); };
  std::vector<double> gc(n, std::numeric_limits<double>::infinity());
  std::vector<int> parent(n, -1);
  std::vector<std::uint8_t> closed(n, 0);
  std::priority_queue<Node, std::vector<Node>, std::greater<Node>> open;
  gc[s] = 0;
  parent[s] = s;
  open.push({norm(goal - start), s});
  while (!open.empty()) {
    const int cur = open.top().i;
    open.pop();
    if (closed[cur]) continue;
    closed[cur] = 1;
    if (cur == t) return gc[t];
    const int cx = cur % g.nx, cy = cur / g.nx;
    const Vec2 pc = pos(cur);
    const int par = parent[cur];
    const Vec2 pp = pos(par);
    for (int k = 0; k < 8; ++k) {
      const int x = cx + kDx[k], y = cy + kDy[k];
      if (!g.inside(x, y)) continue;
      const int ni = g.idx(x, y);
      if (closed[ni] || (g.blocked[ni] && ni != t)) continue;
      const Vec2 pn = pos(ni);
      double ng;
      int np;
      if (par != cur && los(pp, pn)) {  // Theta*: connect to the grandparent when visible
        ng = gc[par] + norm(pn - pp);
        np = par;
      } else {
        if (!los(pc, pn)) continue;
        ng = gc[cur] + norm(pn - pc);
        np = cur;
      }
      if (ng < gc[ni]) {
        gc[ni] = ng;
        parent[ni] = np;
        open.push({ng + norm(goal - pn), ni});
      }
    }
  }
  return std::numeric_limits<double>::infinity();
}

}  // namespace fs::robot::detail
