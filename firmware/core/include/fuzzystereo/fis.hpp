// Mamdani fuzzy inference system of eq. (10)-(12) and Table I, and its 2-D lookup table.
//
// The definition (terms, membership functions, rules) is data, read from common/fis/fis.toml by
// firmware/config; the core only sees this struct. At startup FisLut evaluates the Mamdani system
// (min AND, min implication, max aggregation, centroid) in double precision at every table node;
// per segment the decision is a bilinear table read in fixed point.
#pragma once
#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace fs {

struct FisTerm {
  std::string name;
  std::string mf;             // "trimf" or "trapmf" (scikit-fuzzy semantics)
  std::vector<double> params;
};

struct FisVariable {
  std::string name;
  std::vector<FisTerm> terms;
};

struct FisRule {
  int number = 0;
  int in1 = 0, in2 = 0, out = 0;  // term indices
};

struct FisDefinition {
  std::string name;
  int input_points = 1001;
  int output_points = 1401;
  FisVariable in1, in2, out;
  std::vector<FisRule> rules;
};

// Membership degree of term at x (scikit-fuzzy trimf/trapmf semantics).
double membership(const FisTerm& term, double x);

// Reference Mamdani evaluation in double precision; inputs in [0, 1]. Output in [0, 1].
// Antecedent memberships are interpolated on the input universe samples and the centroid is taken
// over the output universe samples exactly as scikit-fuzzy does (piecewise-linear moment/area).
double fis_evaluate(const FisDefinition& def, double x1, double x2);

// Lookup table: size x size nodes over [0,1]^2, values in Q16 ([0, 1] -> 0 .. 65536).
class FisLut {
 public:
  FisLut() = default;
  FisLut(const FisDefinition& def, int size);
  // Process-wide memo: building the table costs ~66k Mamdani evaluations, so matchers that share a
  // definition and size (eval over several disparity ranges, tests) share one table.
  static std::shared_ptr<const FisLut> cached(const FisDefinition& def, int size);

  int size() const { return size_; }
  // Inputs in Q16 [0, kQ16One]; output Q16. Bilinear between nodes.
  inline std::uint32_t lookup(std::uint32_t a_q16, std::uint32_t b_q16) const;
  // Value of the nearest node (no interpolation): a cheap ranking key.
  std::uint32_t lookup_nearest(std::uint32_t a_q16, std::uint32_t b_q16) const {
    const std::uint32_t n1 = static_cast<std::uint32_t>(size_ - 1);
    const std::uint32_t ia = (std::min<std::uint32_t>(a_q16, 1u << 16) * n1 + (1u << 15)) >> 16;
    const std::uint32_t ib = (std::min<std::uint32_t>(b_q16, 1u << 16) * n1 + (1u << 15)) >> 16;
    return table_[ia * static_cast<std::uint32_t>(size_) + ib];
  }
  const std::vector<std::uint32_t>& table() const { return table_; }

 private:
  int size_ = 0;
  std::vector<std::uint32_t> table_;  // row-major [a][b]
};

// Bilinear read. Node (i, j) sits at (i/(N-1), j/(N-1)). Position a*(N-1) is Q16; the fractional
// parts weight the four nodes in Q16, the 64-bit sum (<= 2^50) is rounded back to Q16.
inline std::uint32_t FisLut::lookup(std::uint32_t a_q16, std::uint32_t b_q16) const {
  constexpr std::uint64_t one = 1u << 16;
  const std::uint64_t n1 = static_cast<std::uint64_t>(size_ - 1);
  const std::uint64_t pa = (a_q16 < one ? a_q16 : one) * n1;
  const std::uint64_t pb = (b_q16 < one ? b_q16 : one) * n1;
  std::uint64_t ia = pa >> 16, ib = pb >> 16;
  std::uint64_t fa = pa & 0xFFFF, fb = pb & 0xFFFF;
  if (ia >= n1) { ia = n1 - 1; fa = one; }
  if (ib >= n1) { ib = n1 - 1; fb = one; }
  const std::uint32_t* r0 = table_.data() + ia * static_cast<std::uint64_t>(size_);
  const std::uint32_t* r1 = r0 + size_;
  const std::uint64_t t00 = r0[ib], t01 = r0[ib + 1], t10 = r1[ib], t11 = r1[ib + 1];
  const std::uint64_t acc = (t00 * (one - fb) + t01 * fb) * (one - fa) + (t10 * (one - fb) + t11 * fb) * fa;  // Q48
  return static_cast<std::uint32_t>((acc + (std::uint64_t(1) << 31)) >> 32);
}

}  // namespace fs
