/* Tabulated BRDFs: table file, MERL binary, built-in anti-glare model,
 * trilinear evaluation and validation (see brdf.h, docs/brdf-format.md). */
#include "lcd/brdf.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/hash.h"
#include "core/outfile.h"

#define DEG (180.0 / M_PI)
#define HEADER_BYTES 24
#define MERL_TH 90
#define MERL_TD 90
#define MERL_PD 180 /* stored phi_diff cells (half of MERL's 360) */
#define MERL_N ((size_t)MERL_TH * MERL_TD * MERL_PD)

int cv_brdf_alloc(int n_theta, int n_phi, cv_brdf **out) {
  *out = NULL;
  if (n_theta < 2 || n_theta > 1801 || n_phi < 2 || n_phi > 3601) return CV_ERR_RANGE;
  cv_brdf *b = calloc(1, sizeof *b);
  if (!b) return CV_ERR_NOMEM;
  b->n_theta = n_theta;
  b->n_phi = n_phi;
  b->d_theta = (M_PI / 2) / (n_theta - 1);
  b->d_phi = M_PI / (n_phi - 1);
  b->f = calloc((size_t)n_theta * n_theta * n_phi * 3, sizeof(float));
  if (!b->f) {
    free(b);
    return CV_ERR_NOMEM;
  }
  snprintf(b->source, sizeof b->source, "(table)");
  *out = b;
  return CV_OK;
}

void cv_brdf_destroy(cv_brdf *b) {
  if (!b) return;
  free(b->f);
  free(b);
}

void cv_brdf_rehash(cv_brdf *b) {
  uint64_t h = cv_hash64_init();
  h = cv_hash64_u64(h, (uint64_t)b->n_theta);
  h = cv_hash64_u64(h, (uint64_t)b->n_phi);
  b->hash = cv_hash64_floats(h, b->f, (size_t)b->n_theta * b->n_theta * b->n_phi * 3);
}

static double clampd(double x, double lo, double hi) { return x < lo ? lo : x > hi ? hi : x; }

void cv_brdf_eval(const cv_brdf *b, double theta_i, double theta_o, double phi_d, float rgb[3]) {
  double xo = clampd(theta_o / b->d_theta, 0, b->n_theta - 1);
  double xi = clampd(theta_i / b->d_theta, 0, b->n_theta - 1);
  double xp = clampd(phi_d / b->d_phi, 0, b->n_phi - 1);
  int io = (int)xo, ii = (int)xi, ip = (int)xp;
  if (io > b->n_theta - 2) io = b->n_theta - 2;
  if (ii > b->n_theta - 2) ii = b->n_theta - 2;
  if (ip > b->n_phi - 2) ip = b->n_phi - 2;
  double to = xo - io, ti = xi - ii, tp = xp - ip;
  double acc[3] = {0, 0, 0};
  for (int a = 0; a < 2; a++)
    for (int c = 0; c < 2; c++)
      for (int d = 0; d < 2; d++) {
        double w = (a ? to : 1 - to) * (c ? ti : 1 - ti) * (d ? tp : 1 - tp);
        const float *e = cv_brdf_at(b, io + a, ii + c, ip + d);
        for (int k = 0; k < 3; k++) acc[k] += w * e[k];
      }
  for (int k = 0; k < 3; k++) rgb[k] = (float)acc[k];
}

static const char chan_name[3] = {'R', 'G', 'B'};

void cv_brdf_cell_weights(double d_theta, int a, double *wa, double *wb) {
  /* g = cos sin = sin(2 theta)/2, G = sin^2/2; by parts,
   * int s g = G(b) - int_0^1 G ds, int_0^1 G ds = 1/4 - (sin 2b - sin 2a) / (8 d) */
  double ta = a * d_theta, tb = (a + 1) * d_theta;
  double sa = sin(ta), sb = sin(tb);
  double tot = (sb * sb - sa * sa) / 2;
  double b = sb * sb / 2 - 0.25 + (sin(2 * tb) - sin(2 * ta)) / (8 * d_theta);
  *wb = b;
  *wa = tot - b;
}

int cv_brdf_validate(const cv_brdf *b, cv_brdf_report *rep, double *albedo_rgb, cv_err *err) {
  const int nt = b->n_theta, np = b->n_phi;
  for (int io = 0; io < nt; io++)
    for (int ii = 0; ii < nt; ii++)
      for (int ip = 0; ip < np; ip++) {
        const float *e = cv_brdf_at(b, io, ii, ip);
        for (int c = 0; c < 3; c++) {
          if (!isfinite(e[c]))
            return cv_err_set(err, CV_ERR_NONFINITE,
                              "%s: entry theta_o=%g theta_i=%g phi_d=%g deg channel %c is %s",
                              b->source, io * b->d_theta * DEG, ii * b->d_theta * DEG,
                              ip * b->d_phi * DEG, chan_name[c], isnan(e[c]) ? "NaN" : "Inf");
          if (e[c] < 0)
            return cv_err_set(err, CV_ERR_RANGE,
                              "%s: entry theta_o=%g theta_i=%g phi_d=%g deg channel %c is "
                              "negative (%g); a BRDF is >= 0",
                              b->source, io * b->d_theta * DEG, ii * b->d_theta * DEG,
                              ip * b->d_phi * DEG, chan_name[c], (double)e[c]);
        }
      }
  cv_brdf_report r;
  memset(&r, 0, sizeof r);
  if (rep) {
    r.merl_missing = rep->merl_missing;
    r.merl_missing_used = rep->merl_missing_used;
  }
  r.first_violation_deg = -1;
  for (int io = 0; io < nt; io++) {
    /* rho(theta_o): exact integral of the interpolated table, both sides */
    double rho[3] = {0, 0, 0};
    for (int ii = 0; ii < nt - 1; ii++) {
      double wa, wb;
      cv_brdf_cell_weights(b->d_theta, ii, &wa, &wb);
      wa *= b->d_phi, wb *= b->d_phi; /* one side; x2 for both, x1/2 for the edge mean */
      for (int ip = 0; ip < np - 1; ip++) {
        const float *e00 = cv_brdf_at(b, io, ii, ip), *e01 = cv_brdf_at(b, io, ii, ip + 1);
        const float *e10 = cv_brdf_at(b, io, ii + 1, ip), *e11 = cv_brdf_at(b, io, ii + 1, ip + 1);
        for (int c = 0; c < 3; c++)
          rho[c] += wa * ((double)e00[c] + e01[c]) + wb * ((double)e10[c] + e11[c]);
      }
    }
    int viol = 0;
    for (int c = 0; c < 3; c++) {
      if (albedo_rgb) albedo_rgb[3 * io + c] = rho[c];
      if (rho[c] > r.albedo_max) {
        r.albedo_max = rho[c];
        r.albedo_max_deg = io * b->d_theta * DEG;
      }
      if (rho[c] > 1 + 1e-3) viol = 1;
    }
    if (viol) {
      if (r.albedo_violations == 0) r.first_violation_deg = io * b->d_theta * DEG;
      r.albedo_violations++;
    }
  }
  if (rep) *rep = r;
  return CV_OK;
}

/* --- files -------------------------------------------------------------- */

static int read_all(const char *path, unsigned char **buf, size_t *len, cv_err *err) {
  *buf = NULL;
  *len = 0;
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open (%s)", path, strerror(errno));
  size_t cap = 1 << 16, n = 0;
  unsigned char *b = malloc(cap);
  while (b) {
    if (n == cap) {
      unsigned char *nb = realloc(b, cap * 2);
      if (!nb) {
        free(b);
        b = NULL;
        break;
      }
      b = nb;
      cap *= 2;
    }
    size_t got = fread(b + n, 1, cap - n, f);
    n += got;
    if (got == 0) break;
  }
  int bad = ferror(f);
  fclose(f);
  if (!b) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory reading the file", path);
  if (bad) {
    free(b);
    return cv_err_set(err, CV_ERR_IO, "%s: read error", path);
  }
  *buf = b;
  *len = n;
  return CV_OK;
}

static uint32_t rd_u32(const unsigned char *p) {
  return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static float rd_f32(const unsigned char *p) {
  uint32_t u = rd_u32(p);
  float f;
  memcpy(&f, &u, sizeof f);
  return f;
}

static double rd_f64(const unsigned char *p) {
  uint64_t u = (uint64_t)rd_u32(p) | (uint64_t)rd_u32(p + 4) << 32;
  double d;
  memcpy(&d, &u, sizeof d);
  return d;
}

static int parse_table(const char *path, const unsigned char *buf, size_t len, cv_brdf **out,
                       cv_err *err) {
  *out = NULL;
  if (len < HEADER_BYTES)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: truncated header (%zu of %d bytes)", path, len,
                      HEADER_BYTES);
  uint32_t ver = rd_u32(buf + 8), nt = rd_u32(buf + 12), np = rd_u32(buf + 16),
           ch = rd_u32(buf + 20);
  if (ver != CV_BRDF_VERSION)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: version %u, this program reads version %d", path,
                      ver, CV_BRDF_VERSION);
  if (nt < 2 || nt > 1801 || np < 2 || np > 3601)
    return cv_err_set(err, CV_ERR_FORMAT,
                      "%s: grid %u x %u: expected n_theta in 2..1801 and n_phi in 2..3601 (91 "
                      "and 181 for 1 degree)",
                      path, nt, np);
  if (ch != 1 && ch != 3)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: %u channels, expected 1 or 3", path, ch);
  size_t n = (size_t)nt * nt * np, want = HEADER_BYTES + n * ch * 4;
  if (len < want)
    return cv_err_set(err, CV_ERR_FORMAT,
                      "%s: truncated: a %ux%ux%u grid of %u channel(s) needs %zu bytes, the file "
                      "has %zu",
                      path, nt, nt, np, ch, want, len);
  if (len > want)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: %zu trailing bytes after the %zu expected", path,
                      len - want, want);
  cv_brdf *b;
  if (cv_brdf_alloc((int)nt, (int)np, &b)) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  const unsigned char *p = buf + HEADER_BYTES;
  for (size_t k = 0; k < n; k++)
    for (int c = 0; c < 3; c++) b->f[3 * k + c] = rd_f32(p + 4 * (k * ch + (ch == 3 ? (size_t)c : 0)));
  snprintf(b->source, sizeof b->source, "%s", path);
  *out = b;
  return CV_OK;
}

/* MERL's coordinate conversion (Matusik et al. 2003, BRDFRead.cpp). */
static void rotate_vector(const double v[3], const double axis[3], double ang, double out[3]) {
  double c = cos(ang), s = sin(ang);
  double d = (axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2]) * (1 - c);
  double cr[3] = {axis[1] * v[2] - axis[2] * v[1], axis[2] * v[0] - axis[0] * v[2],
                  axis[0] * v[1] - axis[1] * v[0]};
  for (int k = 0; k < 3; k++) out[k] = v[k] * c + axis[k] * d + cr[k] * s;
}

size_t cv_brdf_merl_index(double theta_in, double phi_in, double theta_out, double phi_out) {
  double in[3] = {sin(theta_in) * cos(phi_in), sin(theta_in) * sin(phi_in), cos(theta_in)};
  double ou[3] = {sin(theta_out) * cos(phi_out), sin(theta_out) * sin(phi_out), cos(theta_out)};
  double h[3] = {in[0] + ou[0], in[1] + ou[1], in[2] + ou[2]};
  double hl = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
  if (hl > 0)
    for (int k = 0; k < 3; k++) h[k] /= hl;
  else
    h[0] = h[1] = 0, h[2] = 1;
  double th = acos(clampd(h[2], -1, 1)), ph = atan2(h[1], h[0]);
  const double nrm[3] = {0, 0, 1}, bin[3] = {0, 1, 0};
  double tmp[3], diff[3];
  rotate_vector(in, nrm, -ph, tmp);
  rotate_vector(tmp, bin, -th, diff);
  double td = acos(clampd(diff[2], -1, 1)), pd = atan2(diff[1], diff[0]);
  /* theta_half index = sqrt(theta_h / (pi/2) * 90 * 90), non-linear so that
   * the specular peak gets fine cells */
  int ih = 0;
  if (th > 0) {
    ih = (int)sqrt(th / (M_PI / 2) * MERL_TH * MERL_TH);
    if (ih >= MERL_TH) ih = MERL_TH - 1;
  }
  int id = (int)(td / (M_PI / 2) * MERL_TD);
  if (id < 0) id = 0;
  if (id > MERL_TD - 1) id = MERL_TD - 1;
  if (pd < 0) pd += M_PI; /* reciprocity: phi_diff and phi_diff + pi agree */
  int ip = (int)(pd / M_PI * MERL_PD);
  if (ip < 0) ip = 0;
  if (ip > MERL_PD - 1) ip = MERL_PD - 1;
  return (size_t)ip + (size_t)id * MERL_PD + (size_t)ih * MERL_PD * MERL_TD;
}

void cv_brdf_merl_lookup(const double *raw, double theta_in, double phi_in, double theta_out,
                         double phi_out, double rgb[3]) {
  static const double scale[3] = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};
  size_t i = cv_brdf_merl_index(theta_in, phi_in, theta_out, phi_out);
  for (int c = 0; c < 3; c++) rgb[c] = raw[i + (size_t)c * MERL_N] * scale[c];
}

/* Three plausible int32 dimensions: taken as a MERL file, whose parser then
 * names what is wrong with them. */
static int is_merl_header(const unsigned char *buf, size_t len) {
  if (len < 12) return 0;
  for (int k = 0; k < 3; k++) {
    uint32_t d = rd_u32(buf + 4 * k);
    if (d < 1 || d > 100000) return 0;
  }
  return 1;
}

static int parse_merl(const char *path, const unsigned char *buf, size_t len, int n_theta,
                      int n_phi, cv_brdf **out, cv_brdf_report *rep, cv_err *err) {
  *out = NULL;
  if (len < 12) return cv_err_set(err, CV_ERR_FORMAT, "%s: truncated MERL header", path);
  int32_t d[3];
  for (int k = 0; k < 3; k++) d[k] = (int32_t)rd_u32(buf + 4 * k);
  if ((int64_t)d[0] * d[1] * d[2] != (int64_t)MERL_N)
    return cv_err_set(err, CV_ERR_FORMAT,
                      "%s: MERL dimensions %d x %d x %d, expected 90 x 90 x 180", path, d[0], d[1],
                      d[2]);
  size_t want = 12 + 3 * MERL_N * 8;
  if (len != want)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: MERL file of %zu bytes, expected %zu (%s)", path,
                      len, want, len < want ? "truncated" : "trailing bytes");
  double *raw = malloc(3 * MERL_N * sizeof(double));
  if (!raw) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  uint64_t missing = 0;
  for (size_t k = 0; k < 3 * MERL_N; k++) {
    double v = rd_f64(buf + 12 + 8 * k);
    if (!isfinite(v)) {
      size_t c = k / MERL_N, r = k % MERL_N;
      free(raw);
      return cv_err_set(err, CV_ERR_NONFINITE,
                        "%s: MERL entry theta_half index %zu, theta_diff index %zu, phi_diff "
                        "index %zu, channel %c is %s",
                        path, r / (MERL_PD * MERL_TD), (r / MERL_PD) % MERL_TD, r % MERL_PD,
                        chan_name[c], isnan(v) ? "NaN" : "Inf");
    }
    if (v < 0) missing++;
    raw[k] = v;
  }
  cv_brdf *b;
  if (cv_brdf_alloc(n_theta, n_phi, &b)) {
    free(raw);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  uint64_t used = 0;
  for (int io = 0; io < n_theta; io++)
    for (int ii = 0; ii < n_theta; ii++)
      for (int ip = 0; ip < n_phi; ip++) {
        double rgb[3];
        cv_brdf_merl_lookup(raw, ii * b->d_theta, ip * b->d_phi, io * b->d_theta, 0, rgb);
        float *e = cv_brdf_at(b, io, ii, ip);
        int miss = 0;
        for (int c = 0; c < 3; c++) {
          if (rgb[c] < 0) miss = 1;
          e[c] = rgb[c] < 0 ? 0.0f : (float)rgb[c];
        }
        used += miss;
      }
  free(raw);
  snprintf(b->source, sizeof b->source, "%s", path);
  if (rep) {
    memset(rep, 0, sizeof *rep);
    rep->merl_missing = missing;
    rep->merl_missing_used = used;
  }
  *out = b;
  return CV_OK;
}

static int finish(cv_brdf *b, cv_brdf_report *rep, cv_brdf **out, cv_err *err) {
  int st = cv_brdf_validate(b, rep, NULL, err);
  if (st) {
    cv_brdf_destroy(b);
    return st;
  }
  cv_brdf_rehash(b);
  *out = b;
  return CV_OK;
}

int cv_brdf_load_merl(const char *path, int n_theta, int n_phi, cv_brdf **out,
                      cv_brdf_report *rep, cv_err *err) {
  *out = NULL;
  unsigned char *buf;
  size_t len;
  int st = read_all(path, &buf, &len, err);
  if (st) return st;
  cv_brdf *b;
  cv_brdf_report r;
  memset(&r, 0, sizeof r);
  st = parse_merl(path, buf, len, n_theta, n_phi, &b, &r, err);
  free(buf);
  if (st) return st;
  st = finish(b, &r, out, err);
  if (!st && rep) *rep = r;
  return st;
}

int cv_brdf_load(const char *path, cv_brdf **out, cv_brdf_report *rep, cv_err *err) {
  *out = NULL;
  cv_brdf_report r;
  memset(&r, 0, sizeof r);
  int st;
  cv_brdf *b = NULL;
  if (!strcmp(path, CV_BRDF_BUILTIN_ANTIGLARE)) {
    cv_antiglare_params p;
    cv_antiglare_default(&p);
    if ((st = cv_brdf_antiglare(&p, 91, 181, &b)))
      return cv_err_set(err, st, "%s: cannot tabulate", path);
  } else {
    unsigned char *buf;
    size_t len;
    if ((st = read_all(path, &buf, &len, err))) return st;
    if (len >= 8 && !memcmp(buf, CV_BRDF_MAGIC, 8))
      st = parse_table(path, buf, len, &b, err);
    else if (is_merl_header(buf, len))
      st = parse_merl(path, buf, len, 91, 181, &b, &r, err);
    else
      st = cv_err_set(err, CV_ERR_FORMAT,
                      "%s: neither a BRDF table (magic %s, docs/brdf-format.md) nor a MERL "
                      "binary (header 90 90 180)",
                      path, CV_BRDF_MAGIC);
    free(buf);
    if (st) return st;
  }
  st = finish(b, &r, out, err);
  if (!st && rep) *rep = r;
  return st;
}

static void wr_u32(unsigned char *p, uint32_t v) {
  for (int k = 0; k < 4; k++) p[k] = (unsigned char)(v >> (8 * k));
}

int cv_brdf_write(const char *path, const cv_brdf *b, cv_err *err) {
  cv_outfile o;
  int st = cv_outfile_open(&o, path, 1, err);
  if (st) return st;
  unsigned char hdr[HEADER_BYTES];
  memcpy(hdr, CV_BRDF_MAGIC, 8);
  wr_u32(hdr + 8, CV_BRDF_VERSION);
  wr_u32(hdr + 12, (uint32_t)b->n_theta);
  wr_u32(hdr + 16, (uint32_t)b->n_phi);
  wr_u32(hdr + 20, 3);
  int ok = fwrite(hdr, 1, sizeof hdr, o.f) == sizeof hdr;
  size_t n = (size_t)b->n_theta * b->n_theta * b->n_phi * 3;
  unsigned char chunk[4096];
  for (size_t k = 0; k < n && ok;) {
    size_t m = 0;
    for (; m < sizeof chunk / 4 && k < n; m++, k++) {
      uint32_t u;
      memcpy(&u, &b->f[k], 4);
      wr_u32(chunk + 4 * m, u);
    }
    ok = fwrite(chunk, 4, m, o.f) == m;
  }
  if (!ok) {
    cv_outfile_abort(&o);
    return cv_err_set(err, CV_ERR_IO, "%s: write failed", path);
  }
  return cv_outfile_commit(&o, err);
}

/* --- built-in anti-glare model ------------------------------------------ */

void cv_antiglare_default(cv_antiglare_params *p) {
  p->rd = 0.008;
  p->rs = 0.01;
  p->sigma_s_deg = 1.0;
  p->rh = 0.04;
  p->sigma_h_deg = 6.0;
}

int cv_brdf_antiglare(const cv_antiglare_params *p, int n_theta, int n_phi, cv_brdf **out) {
  *out = NULL;
  if (!(p->rd >= 0 && p->rs >= 0 && p->rh >= 0) || !(p->sigma_s_deg > 0 && p->sigma_s_deg <= 90) ||
      !(p->sigma_h_deg > 0 && p->sigma_h_deg <= 90))
    return CV_ERR_RANGE;
  cv_brdf *b;
  int st = cv_brdf_alloc(n_theta, n_phi, &b);
  if (st) return st;
  double ss = p->sigma_s_deg / DEG, sh = p->sigma_h_deg / DEG;
  double ns = 1 / (2 * M_PI * ss * ss), nh = 1 / (2 * M_PI * sh * sh);
  for (int io = 0; io < n_theta; io++) {
    double to = io * b->d_theta, so = sin(to), co = cos(to);
    for (int ii = 0; ii < n_theta; ii++) {
      double ti = ii * b->d_theta, si = sin(ti), ci = cos(ti);
      double sym = 2 / fmax(ci + co, 0.1);
      for (int ip = 0; ip < n_phi; ip++) {
        double ph = ip * b->d_phi;
        /* cos of the angle between w_i and the mirror (-sin to, 0, cos to) of w_o */
        double ca = -si * cos(ph) * so + ci * co;
        double al = acos(clampd(ca, -1, 1));
        double f = p->rd / M_PI + (p->rs * ns * exp(-al * al / (2 * ss * ss)) +
                                   p->rh * nh * exp(-al * al / (2 * sh * sh))) * sym;
        float *e = cv_brdf_at(b, io, ii, ip);
        e[0] = e[1] = e[2] = (float)f;
      }
    }
  }
  snprintf(b->source, sizeof b->source, "%s", CV_BRDF_BUILTIN_ANTIGLARE);
  cv_brdf_rehash(b);
  *out = b;
  return CV_OK;
}
