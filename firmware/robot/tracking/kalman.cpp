// Constant-velocity Kalman filter, paper eq. (26)-(32). Eigen fixed-size 4x4 matrices.
#include <cmath>
#include "fuzzystereo/robot/kalman.hpp"

#include <Eigen/Dense>

namespace fs::robot {

void CvKalman::init(double px, double py, double pos_var, double vel_var) {
  x_ << px, py, 0.0, 0.0;
  P_ = Vec4(pos_var, pos_var, vel_var, vel_var).asDiagonal();  // eq. (30)
}

Mat4 CvKalman::F(double dt) {  // eq. (28): [[I, dt I], [0, I]]
  Mat4 f = Mat4::Identity();
  f(0, 2) = dt;
  f(1, 3) = dt;
  return f;
}

Mat4 CvKalman::Q(double dt, double accel_sigma) {
  // Discrete white-noise acceleration: the velocity change over dt is a random input (the paper's
  // "variation in velocity ... treated as a random process", B u = 0), G = [dt^2/2 I; dt I],
  // Q = G G^T sa^2.
  const double s2 = accel_sigma * accel_sigma;
  const double q11 = s2 * dt * dt * dt * dt / 4.0, q12 = s2 * dt * dt * dt / 2.0, q22 = s2 * dt * dt;
  Mat4 q = Mat4::Zero();
  q(0, 0) = q(1, 1) = q11;
  q(0, 2) = q(2, 0) = q(1, 3) = q(3, 1) = q12;
  q(2, 2) = q(3, 3) = q22;
  return q;
}

void CvKalman::propagate(const Mat4& f, double dt, double accel_sigma) {
  x_ = f * x_;                                       // eq. (26)/(29), B u = 0
  P_ = f * P_ * f.transpose() + Q(dt, accel_sigma);  // eq. (26)
}

void CvKalman::predict(double dt, double accel_sigma) { propagate(F(dt), dt, accel_sigma); }

Mat4 CvKalman::F_damped(double dt, double tau) {
  const double a = std::exp(-dt / tau);
  Mat4 f = Mat4::Identity();
  f(0, 2) = f(1, 3) = -tau * std::expm1(-dt / tau);  // tau (1 - a), exact for tau >> dt too
  f(2, 2) = f(3, 3) = a;
  return f;
}

void CvKalman::predict_damped(double dt, double tau, double accel_sigma) {
  propagate(F_damped(dt, tau), dt, accel_sigma);
}

void CvKalman::add_process_noise(double dt, double accel_sigma) {
  P_ += Q(dt, accel_sigma);
}

double CvKalman::position_nis(double px, double py, double pos_var) const {
  const Eigen::Matrix2d S = P_.topLeftCorner<2, 2>() + pos_var * Eigen::Matrix2d::Identity();
  const Eigen::Vector2d nu(px - x_(0), py - x_(1));
  return nu.dot(S.ldlt().solve(nu));
}

void CvKalman::update(const Vec4& z, const Mat4& R) {
  // H = I: eq. (31) K = P (P + R)^-1, eq. (32) x += K (z - x), P -= K P.
  const Mat4 S = P_ + R;
  const Mat4 K = P_ * S.inverse();
  x_ = x_ + K * (z - x_);
  P_ = P_ - K * P_;
  P_ = 0.5 * (P_ + P_.transpose());  // keep symmetric against round-off
}

void CvKalman::update_position(double px, double py, double pos_var) {
  // eq. (31)-(32) with H = [I 0] (2x4).
  Eigen::Matrix<double, 2, 4> H = Eigen::Matrix<double, 2, 4>::Zero();
  H(0, 0) = H(1, 1) = 1.0;
  const Eigen::Matrix2d S = H * P_ * H.transpose() + pos_var * Eigen::Matrix2d::Identity();
  const Eigen::Matrix<double, 4, 2> K = P_ * H.transpose() * S.inverse();
  const Eigen::Vector2d y = Eigen::Vector2d(px, py) - H * x_;
  x_ = x_ + K * y;
  P_ = P_ - K * H * P_;
  P_ = 0.5 * (P_ + P_.transpose());
}

double CvKalman::pos_sigma() const {
  const Eigen::Matrix2d pp = P_.topLeftCorner<2, 2>();
  const double tr = pp.trace(), det = pp.determinant();
  const double disc = std::sqrt(std::max(0.0, tr * tr / 4.0 - det));
  return std::sqrt(std::max(0.0, tr / 2.0 + disc));
}

}  // namespace fs::robot
