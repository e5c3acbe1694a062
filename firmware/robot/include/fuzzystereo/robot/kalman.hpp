// Constant-velocity Kalman filter on the ground plane, in the paper's form, eq. (26)-(32):
//   state x = [p; v] (eq. 27), p and v 2-D world-frame vectors [m], [m/s];
//   predict  x = F x (+ B u = 0, the paper drops the control term), P = F P F^T + Q   eq. (26)
//   F = [[I, dt I], [0, I]]                                                         eq. (28)-(29)
//   P initially diagonal                                                            eq. (30)
//   K = P H^T (H P H^T + R)^-1                                                      eq. (31)
//   x = x + K (z - H x), P = P - K H P                                              eq. (32)
// H = I (the paper: measurement space = state space), so z = [p_meas; v_meas] where v_meas is the
// finite difference to the previous measurement of the same track (see docs/robot.md for why and
// for R of that velocity). Q is the discrete white-noise-acceleration model.
#pragma once
#include <Eigen/Core>

namespace fs::robot {

using Vec4 = Eigen::Matrix<double, 4, 1>;
using Mat4 = Eigen::Matrix<double, 4, 4>;

class CvKalman {
 public:
  // eq. (30): P0 = diag(pos_var, pos_var, vel_var, vel_var); velocity starts at 0.
  void init(double px, double py, double pos_var, double vel_var);

  // eq. (26) with F of eq. (28) and the white-noise-acceleration Q (accel_sigma [m/s^2]):
  //   Q = sa^2 [[dt^4/4 I, dt^3/2 I], [dt^3/2 I, dt^2 I]].
  void predict(double dt, double accel_sigma);
  // Outside the paper (a track without measurements, [tracker] coast_decay_s, docs/robot.md "Session 47"):
  // eq. (26) with the velocity decaying at time constant tau [s] (an integrated Ornstein-Uhlenbeck velocity):
  //   F = [[I, tau (1 - e^{-dt/tau}) I], [0, e^{-dt/tau} I]], the same Q.
  void predict_damped(double dt, double tau, double accel_sigma);
  static Mat4 F_damped(double dt, double tau);

  // eq. (31)-(32) with H = I and a full 4-D measurement z = [p; v] with covariance R.
  void update(const Vec4& z, const Mat4& R);
  // eq. (31)-(32) with H = [I 0] (position only; used for the first update of a track, before a
  // finite-difference velocity exists, and when velocity measurements are disabled).
  void update_position(double px, double py, double pos_var);

  // P += Q(dt, accel_sigma): the process noise of a prediction over dt added afterwards (the
  // maneuver switch raises a track's Q level for the interval it was detected in; Q is linear in
  // accel_sigma^2, so Q(dt, hi) = Q(dt, lo) + Q(dt, sqrt(hi^2 - lo^2))).
  void add_process_noise(double dt, double accel_sigma);
  // Normalised innovation squared of a position measurement against the current (predicted) state:
  // nu^T S^-1 nu with nu = z - [px, py], S = P_pp + pos_var I (chi-square, 2 dof, when the model fits).
  double position_nis(double px, double py, double pos_var) const;

  static Mat4 F(double dt);                        // eq. (28)
  static Mat4 Q(double dt, double accel_sigma);

  const Vec4& x() const { return x_; }
  const Mat4& P() const { return P_; }
  double px() const { return x_(0); }
  double py() const { return x_(1); }
  double vx() const { return x_(2); }
  double vy() const { return x_(3); }
  // Largest position standard deviation (sqrt of the largest eigenvalue of the 2x2 position block).
  double pos_sigma() const;

 private:
  // x = f x, P = f P f^T + Q(dt, accel_sigma): the prediction step for a given transition f.
  void propagate(const Mat4& f, double dt, double accel_sigma);
  Vec4 x_ = Vec4::Zero();
  Mat4 P_ = Mat4::Identity();
};

}  // namespace fs::robot
