// The EWA projection of one primitive, forward and backward: the per-primitive maths that the
// CPU loops (project.cpp) and the CUDA kernels (project_cuda.cu) both run, in double (the 2x2
// covariance of a thin, long primitive loses its determinant to cancellation in float32).
// Mirrors renderer/_torch_ref.py: project().
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "constants.h"
#include "portable.h"
#include "project.h"

namespace edgedog {
namespace projection {

// Everything the forward pass derives for one primitive, kept for its backward pass.
struct Projected {
  bool valid;
  double p[3];              // camera-space position
  double z;                 // depth (1 where culled, to stay finite)
  double tx, ty;            // directions clamped to the frustum slack, times z
  double clamp_x, clamp_y;  // x/z and y/z after clamping
  double slope_x, slope_y;  // d clamp / d (x/z): 1 inside, 0 where clamped
  double J[6];              // 2x3 EWA Jacobian, row-major
  double qn[4];             // normalised quaternion
  double inv_qnorm;
  double Rq[9];   // rotation of the primitive
  double T[6];    // J R_cam (2x3)
  double TM[6];   // T R_q S (2x3)
  double cov[3];  // dilated 2D covariance (a, b, c)
  double det;
};

EDGEDOG_HD inline void quat_to_rot(const double* q, double* R) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  R[0] = 1 - 2 * (y * y + z * z);
  R[1] = 2 * (x * y - w * z);
  R[2] = 2 * (x * z + w * y);
  R[3] = 2 * (x * y + w * z);
  R[4] = 1 - 2 * (x * x + z * z);
  R[5] = 2 * (y * z - w * x);
  R[6] = 2 * (x * z - w * y);
  R[7] = 2 * (y * z + w * x);
  R[8] = 1 - 2 * (x * x + y * y);
}

EDGEDOG_HD inline double clamp(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

EDGEDOG_HD inline Projected project_one(const PinholeCamera& cam, const ProjectInputs& in, int64_t i) {
  Projected r{};
  const float* m = in.means + 3 * i;
  for (int k = 0; k < 3; ++k) {
    r.p[k] = cam.R[3 * k] * m[0] + cam.R[3 * k + 1] * m[1] + cam.R[3 * k + 2] * m[2] + cam.t[k];
  }
  r.valid = r.p[2] > cam.near;
  r.z = r.valid ? r.p[2] : 1.0;
  const double lim_x = kFrustumSlack * 0.5 * cam.width / cam.fx;
  const double lim_y = kFrustumSlack * 0.5 * cam.height / cam.fy;
  const double rx = r.p[0] / r.z, ry = r.p[1] / r.z;
  r.clamp_x = clamp(rx, -lim_x, lim_x);
  r.clamp_y = clamp(ry, -lim_y, lim_y);
  r.slope_x = (rx >= -lim_x && rx <= lim_x) ? 1.0 : 0.0;  // torch.clamp's gradient is inclusive
  r.slope_y = (ry >= -lim_y && ry <= lim_y) ? 1.0 : 0.0;
  r.tx = r.z * r.clamp_x;
  r.ty = r.z * r.clamp_y;
  const double z2 = r.z * r.z;
  r.J[0] = cam.fx / r.z;
  r.J[1] = 0;
  r.J[2] = -cam.fx * r.tx / z2;
  r.J[3] = 0;
  r.J[4] = cam.fy / r.z;
  r.J[5] = -cam.fy * r.ty / z2;

  const float* q = in.quats + 4 * i;
  double norm2 = 0;
  for (int k = 0; k < 4; ++k) norm2 += double(q[k]) * q[k];
  r.inv_qnorm = 1.0 / sqrt(norm2 < 1e-24 ? 1e-24 : norm2);  // as std::max: NaN stays NaN
  for (int k = 0; k < 4; ++k) r.qn[k] = q[k] * r.inv_qnorm;
  quat_to_rot(r.qn, r.Rq);

  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 3; ++col) {
      r.T[3 * row + col] =
          r.J[3 * row] * cam.R[col] + r.J[3 * row + 1] * cam.R[3 + col] + r.J[3 * row + 2] * cam.R[6 + col];
    }
  }
  const float* s = in.scales + 3 * i;
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 3; ++col) {
      r.TM[3 * row + col] =
          (r.T[3 * row] * r.Rq[col] + r.T[3 * row + 1] * r.Rq[3 + col] + r.T[3 * row + 2] * r.Rq[6 + col]) *
          s[col];
    }
  }
  const double* a = r.TM;
  const double* b = r.TM + 3;
  r.cov[0] = a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + in.eps2d;
  r.cov[1] = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  r.cov[2] = b[0] * b[0] + b[1] * b[1] + b[2] * b[2] + in.eps2d;
  r.det = r.cov[0] * r.cov[2] - r.cov[1] * r.cov[1];
  return r;
}

// Writes primitive i's outputs.
EDGEDOG_HD inline void forward_one(const PinholeCamera& cam, const ProjectInputs& in,
                                   const ProjectOutputs& out, int64_t i) {
  const Projected r = project_one(cam, in, i);
  out.valid[i] = r.valid;
  out.means2d[2 * i] = float(cam.fx * r.p[0] / r.z + cam.cx);
  out.means2d[2 * i + 1] = float(cam.fy * r.p[1] / r.z + cam.cy);
  out.conics[3 * i] = float(r.cov[2] / r.det);
  out.conics[3 * i + 1] = float(-r.cov[1] / r.det);
  out.conics[3 * i + 2] = float(r.cov[0] / r.det);
  out.depths[i] = r.valid ? float(r.p[2]) : 0.f;
  const double support = r.valid ? (in.support_q[i] < 0.f ? 0.0 : double(in.support_q[i])) : 0.0;
  out.extents[2 * i] = float(sqrt(support * r.cov[0]));
  out.extents[2 * i + 1] = float(sqrt(support * r.cov[2]));
}

// Writes primitive i's gradients (zeros when it is culled).
EDGEDOG_HD inline void backward_one(const PinholeCamera& cam, const ProjectInputs& in,
                                    const ProjectGradOutputs& go, const ProjectGradInputs& gi, int64_t i) {
  float* g_mean = gi.means + 3 * i;
  float* g_scale = gi.scales + 3 * i;
  float* g_quat = gi.quats + 4 * i;
  const Projected r = project_one(cam, in, i);
  if (!r.valid) {
    for (int k = 0; k < 3; ++k) g_mean[k] = g_scale[k] = 0.f;
    for (int k = 0; k < 4; ++k) g_quat[k] = 0.f;
    return;
  }
  // conic = (c, -b, a) / det of the covariance (a, b, c).
  const double gA = go.conics[3 * i], gB = go.conics[3 * i + 1], gC = go.conics[3 * i + 2];
  const double a = r.cov[0], b = r.cov[1], c = r.cov[2], det2 = r.det * r.det;
  const double g_a = (-c * c * gA + b * c * gB - b * b * gC) / det2;
  const double g_b = (2 * b * c * gA - (r.det + 2 * b * b) * gB + 2 * a * b * gC) / det2;
  const double g_c = (-b * b * gA + a * b * gB - a * a * gC) / det2;
  // cov = TM TM^T (+ eps): with G symmetric (off-diagonals g_b / 2), dL/dTM = 2 G TM.
  double g_TM[6];
  for (int col = 0; col < 3; ++col) {
    g_TM[col] = 2 * g_a * r.TM[col] + g_b * r.TM[3 + col];
    g_TM[3 + col] = g_b * r.TM[col] + 2 * g_c * r.TM[3 + col];
  }
  // TM = T Rq S.
  const float* s = in.scales + 3 * i;
  double g_T[6] = {0, 0, 0, 0, 0, 0};
  double g_Rq[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  for (int col = 0; col < 3; ++col) {
    double g_scale_col = 0;
    for (int k = 0; k < 3; ++k) {
      // TM[row, col] = sum_k T[row, k] Rq[k, col] s[col]
      const double g_M = r.T[k] * g_TM[col] + r.T[3 + k] * g_TM[3 + col];  // dL/d(Rq S)[k, col]
      g_Rq[3 * k + col] = g_M * s[col];
      g_scale_col += g_M * r.Rq[3 * k + col];
      g_T[k] += g_TM[col] * r.Rq[3 * k + col] * s[col];
      g_T[3 + k] += g_TM[3 + col] * r.Rq[3 * k + col] * s[col];
    }
    g_scale[col] = float(g_scale_col);
  }
  // Rq from the normalised quaternion, then through the normalisation.
  const double w = r.qn[0], x = r.qn[1], y = r.qn[2], z = r.qn[3];
  const double* G = g_Rq;
  double g_qn[4];
  g_qn[0] = 2 * (-z * G[1] + y * G[2] + z * G[3] - x * G[5] - y * G[6] + x * G[7]);
  g_qn[1] =
      2 * (y * G[1] + z * G[2] + y * G[3] - 2 * x * G[4] - w * G[5] + z * G[6] + w * G[7] - 2 * x * G[8]);
  g_qn[2] =
      2 * (-2 * y * G[0] + x * G[1] + w * G[2] + x * G[3] + z * G[5] - w * G[6] + z * G[7] - 2 * y * G[8]);
  g_qn[3] =
      2 * (-2 * z * G[0] - w * G[1] + x * G[2] + w * G[3] - 2 * z * G[4] + y * G[5] + x * G[6] + y * G[7]);
  const double dot = w * g_qn[0] + x * g_qn[1] + y * g_qn[2] + z * g_qn[3];
  for (int k = 0; k < 4; ++k) g_quat[k] = float((g_qn[k] - r.qn[k] * dot) * r.inv_qnorm);
  // T = J R_cam.
  double g_J[6];
  for (int row = 0; row < 2; ++row) {
    for (int k = 0; k < 3; ++k) {
      g_J[3 * row + k] = g_T[3 * row] * cam.R[3 * k] + g_T[3 * row + 1] * cam.R[3 * k + 1] +
                         g_T[3 * row + 2] * cam.R[3 * k + 2];
    }
  }
  // J(z, tx, ty), tx = z clamp(x / z).
  const double zz = r.z, z2 = zz * zz, z3 = z2 * zz;
  double g_p[3] = {0, 0, 0};
  const double g_tx = -cam.fx / z2 * g_J[2];
  const double g_ty = -cam.fy / z2 * g_J[5];
  g_p[2] += -cam.fx / z2 * g_J[0] + 2 * cam.fx * r.tx / z3 * g_J[2] - cam.fy / z2 * g_J[4] +
            2 * cam.fy * r.ty / z3 * g_J[5];
  g_p[0] += g_tx * r.slope_x;
  g_p[2] += g_tx * (r.clamp_x - r.slope_x * r.p[0] / zz);
  g_p[1] += g_ty * r.slope_y;
  g_p[2] += g_ty * (r.clamp_y - r.slope_y * r.p[1] / zz);
  // means2d = (fx x / z + cx, fy y / z + cy); depth = z.
  const double gu = go.means2d[2 * i], gv = go.means2d[2 * i + 1];
  g_p[0] += gu * cam.fx / zz;
  g_p[1] += gv * cam.fy / zz;
  g_p[2] += -gu * cam.fx * r.p[0] / z2 - gv * cam.fy * r.p[1] / z2 + go.depths[i];
  for (int k = 0; k < 3; ++k) {
    g_mean[k] = float(cam.R[k] * g_p[0] + cam.R[3 + k] * g_p[1] + cam.R[6 + k] * g_p[2]);
  }
}

}  // namespace projection
}  // namespace edgedog
