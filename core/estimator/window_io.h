#pragma once
// A captured estimator window (WindowSnapshot, core/estimator/estimator.h) on disk: a
// whitespace-separated text format, gzip-compressed (zlib; plain text is read too), with every
// floating-point number written with 17 significant digits so that doubles round-trip exactly — a
// window restored from its file is bit-identical to the captured one. Format version 1:
//
//   marglab-window 1
//   dataset <name>  variant <name>  frame_index <k>  mode vo|vio
//   config <n>\n<n bytes of the estimator's TOML config>
//   rig <cam0: fx fy cx cy w h> <cam1: …> <T_i_c0: qx qy qz qw tx ty tz> <T_i_c1: …>
//   imu <gyro_nd gyro_rw accel_nd accel_rw> <sample_period_s> <g_w xyz> <N>
//       then N samples: t_ns gx gy gz ax ay az
//   failed_solves <k>
//   frames <N>, then per frame: id t_ns is_kf linearized has_sb sb_linearized
//       T_w_i(7) T_w_i_lin(7) speed_bias(9) speed_bias_lin(9)
//   landmarks <N>, then per landmark: id host u v ρ n_obs, then n_obs × (frame u0 v0 has_right u1
//   v1) imu_links <N>, then per factor: from to b_g(3) b_a(3)     (re-preintegrated on restore)
//   prior <sqrt|hessian> <n_blocks>, then per block: frame block(0 pose|1 speed-bias) offset
//       T0(7) sb0(9); then the matrices J (rows cols, row-major), r, H, b and the scalar c
//   after <0|1> [lm_iterations cost_initial cost_final, frames <N> × (id T_w_i(7) sb(9)),
//       landmarks <N> × (id u v ρ)]
//   end
//
// Poses are (qx qy qz qw tx ty tz) of the unit quaternion and translation.

#include <string>

#include "core/estimator/estimator.h"

namespace marglab {

// Writes `path` atomically (temporary name, then rename); gzip-compressed when it ends in .gz.
void writeWindow(const WindowSnapshot& window, const std::string& path);
// Throws InputError(path, 0, what) on a malformed or truncated file.
WindowSnapshot readWindow(const std::string& path);

}  // namespace marglab
