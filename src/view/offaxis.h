/* Kooima 2008, "Generalized Perspective Projection": the off-axis frustum of
 * a tracked eye looking at a fixed rectangular screen, as OpenGL matrices.
 * pa lower-left, pb lower-right, pc upper-left corner; the screen normal
 * vn = norm((pb-pa) x (pc-pa)) points towards the eye.
 *   vr = norm(pb-pa), vu = norm(pc-pa); va = pa-pe, vb = pb-pe, vc = pc-pe;
 *   d = -vn.va;  l = vr.va n/d, r = vr.vb n/d, b = vu.va n/d, t = vu.vc n/d;
 *   P = frustum(l, r, b, t, n, f) * M^T(vr, vu, vn) * T(-pe)
 * Computed in double; matrices stored as float, column-major (m[col*4+row]),
 * OpenGL clip-space conventions (NDC z in [-1, 1]). */
#ifndef CV_VIEW_OFFAXIS_H
#define CV_VIEW_OFFAXIS_H

/* Relative tolerance on |cos| of the angle between pb-pa and pc-pa. */
#define CV_OFFAXIS_RECT_TOL 1e-3

typedef struct cv_offaxis {
  double vr[3], vu[3], vn[3]; /* screen right, up, normal (towards the eye) */
  double l, r, b, t, n, f;    /* frustum extents on the near plane */
  float proj[16];             /* frustum(l, r, b, t, n, f) */
  float view[16];             /* M^T(vr, vu, vn) * T(-pe): world -> eye */
  float viewproj[16];         /* proj * view (computed in double, then rounded) */
  double viewproj_d[16];      /* proj * view in double (for CPU checks) */
} cv_offaxis;

/* Fills *out for eye pe and clip planes 0 < n < f.  Errors (CV_ERR_INVALID,
 * *out untouched): NULL, non-finite input, zero-length edges, non-rectangular
 * corners (|cos angle(pb-pa, pc-pa)| > CV_OFFAXIS_RECT_TOL), eye on or behind
 * the screen (d <= 1e-9), bad n/f. */
int cv_offaxis_compute(const double pa[3], const double pb[3], const double pc[3],
                       const double pe[3], double n, double f, cv_offaxis *out);

/* Left and right eye positions: head -/+ separation/2 along the head's right
 * axis normalize(gaze x (0,1,0)); when gaze is (nearly) vertical the right
 * axis falls back to +X.  Never fails; NULL-free arguments expected. */
void cv_head_eyes(const double head[3], const double gaze[3], double separation, double left[3],
                  double right[3]);

/* Transforms world point p by m (column-major 4x4, double) to NDC
 * (x, y, z after the divide); returns clip w (<= 0: behind the eye). */
double cv_offaxis_project(const double m[16], const double p[3], double ndc[3]);

#endif
