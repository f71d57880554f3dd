/* Tracker calibration (see tracker_calib.h). */
#include "service/tracker_calib.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/json_keys.h"
#include "mesh/place.h"
#include "io/textfile.h"

void cv_tracker_config_default(cv_tracker_config *c) {
  memset(c, 0, sizeof *c);
  snprintf(c->source, sizeof c->source, "(defaults)");
  c->unit_m = 0.001;
  cv_rotation_xyz_deg(c->room_rotate_deg, c->room_R);
  c->body_id = 1;
  c->forward[2] = -1;
  c->up[1] = 1;
  c->ipd = 0.064;
  c->port = 5000;
  snprintf(c->bind, sizeof c->bind, "0.0.0.0");
}

static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void cross3(const double a[3], const double b[3], double o[3]) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}
static int normalise(double v[3]) {
  double n = sqrt(dot3(v, v));
  if (!(n > 1e-9) || !isfinite(n)) return -1;
  for (int k = 0; k < 3; k++) v[k] /= n;
  return 0;
}
/* o = A v, A row-major */
static void mulv(const double A[9], const double v[3], double o[3]) {
  for (int i = 0; i < 3; i++) o[i] = A[3 * i] * v[0] + A[3 * i + 1] * v[1] + A[3 * i + 2] * v[2];
}

/* ---- config ------------------------------------------------------------- */

typedef struct {
  const char *file;
  cv_err *err;
} ctx;

static int bad(ctx *x, const char *field, const char *what) {
  return cv_err_set(x->err, CV_ERR_CONFIG, "%s: %s: %s", x->file, field, what);
}

static int only(ctx *x, const cJSON *o, const char *path, const char *const *keys) {
  if (!cJSON_IsObject(o)) return bad(x, path[0] ? path : "(top level)", "expected an object");
  const cJSON *it;
  cJSON_ArrayForEach(it, o) {
    if (!cv_json_key_allowed(it->string, keys)) {
      char f[160], list[200];
      snprintf(f, sizeof f, "%s%s%.100s", path, path[0] ? "." : "", it->string);
      cv_json_key_list(keys, list, sizeof list);
      char what[240];
      snprintf(what, sizeof what, "unknown field (expected one of: %s)", list);
      return bad(x, f, what);
    }
  }
  return CV_OK;
}

static int vec3(ctx *x, const cJSON *o, const char *key, const char *field, double out[3]) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return CV_OK;
  if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != 3) return bad(x, field, "expected [x, y, z]");
  for (int k = 0; k < 3; k++) {
    const cJSON *e = cJSON_GetArrayItem(v, k);
    if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble) || fabs(e->valuedouble) > 1e6)
      return bad(x, field, "expected [x, y, z] of finite numbers");
    out[k] = e->valuedouble;
  }
  return CV_OK;
}

static int num(ctx *x, const cJSON *o, const char *key, const char *field, double lo, double hi,
               double *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return CV_OK;
  if (!cJSON_IsNumber(v) || !(v->valuedouble >= lo && v->valuedouble <= hi)) {
    char what[96];
    snprintf(what, sizeof what, "expected a number in [%g, %g]", lo, hi);
    return bad(x, field, what);
  }
  *out = v->valuedouble;
  return CV_OK;
}

static int str(ctx *x, const cJSON *o, const char *key, const char *field, char *out, size_t cap) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return CV_OK;
  if (!cJSON_IsString(v) || strlen(v->valuestring) >= cap) return bad(x, field, "expected a short string");
  snprintf(out, cap, "%s", v->valuestring);
  return CV_OK;
}

static int parse_root(ctx *x, const cJSON *root, cv_tracker_config *c) {
  static const char *const keys[] = {"units", "room_to_cave", "body_id", "forward", "up",
                                     "eye_offset", "ipd", "udp", NULL};
  int st = only(x, root, "", keys);
  if (st) return st;
  const cJSON *u = cJSON_GetObjectItemCaseSensitive(root, "units");
  if (u) {
    cv_err e;
    char what[300];
    if (cJSON_IsNumber(u) && isfinite(u->valuedouble) && u->valuedouble > 0) {
      c->unit_m = u->valuedouble;
    } else if (!cJSON_IsString(u) || cv_parse_units(u->valuestring, &c->unit_m, &e)) {
      snprintf(what, sizeof what, "%.250s",
               cJSON_IsString(u) ? e.msg : "expected mm, cm, m, in, ft or metres per unit");
      return bad(x, "units", what);
    }
  }
  const cJSON *rt = cJSON_GetObjectItemCaseSensitive(root, "room_to_cave");
  if (rt) {
    static const char *const rk[] = {"rotate_deg", "translate", NULL};
    if ((st = only(x, rt, "room_to_cave", rk))) return st;
    if ((st = vec3(x, rt, "rotate_deg", "room_to_cave.rotate_deg", c->room_rotate_deg))) return st;
    if ((st = vec3(x, rt, "translate", "room_to_cave.translate", c->room_T))) return st;
    cv_rotation_xyz_deg(c->room_rotate_deg, c->room_R);
  }
  double id = c->body_id;
  if ((st = num(x, root, "body_id", "body_id", 0, 1e6, &id))) return st;
  if (id != floor(id)) return bad(x, "body_id", "expected an integer");
  c->body_id = (int)id;
  if ((st = vec3(x, root, "forward", "forward", c->forward))) return st;
  if ((st = vec3(x, root, "up", "up", c->up))) return st;
  if ((st = vec3(x, root, "eye_offset", "eye_offset", c->eye_offset))) return st;
  if ((st = num(x, root, "ipd", "ipd", 0.0, 0.1, &c->ipd))) return st;
  /* forward and up: unit, up orthogonalised against forward */
  if (normalise(c->forward)) return bad(x, "forward", "expected a non-zero vector");
  double d = dot3(c->up, c->forward);
  for (int k = 0; k < 3; k++) c->up[k] -= d * c->forward[k];
  if (normalise(c->up)) return bad(x, "up", "expected a vector not parallel to forward");
  const cJSON *udp = cJSON_GetObjectItemCaseSensitive(root, "udp");
  if (udp) {
    static const char *const uk[] = {"port", "bind", "multicast", "interface", NULL};
    if ((st = only(x, udp, "udp", uk))) return st;
    double port = c->port;
    if ((st = num(x, udp, "port", "udp.port", 1, 65535, &port))) return st;
    if (port != floor(port)) return bad(x, "udp.port", "expected an integer");
    c->port = (int)port;
    if ((st = str(x, udp, "bind", "udp.bind", c->bind, sizeof c->bind))) return st;
    if ((st = str(x, udp, "multicast", "udp.multicast", c->multicast, sizeof c->multicast)))
      return st;
    if ((st = str(x, udp, "interface", "udp.interface", c->iface, sizeof c->iface))) return st;
  }
  return CV_OK;
}

int cv_tracker_config_parse(const char *text, const char *name, cv_tracker_config *c, cv_err *err) {
  cv_tracker_config_default(c);
  snprintf(c->source, sizeof c->source, "%s", name);
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
  if (!root) {
    int line, col;
    char what[128];
    cv_json_syntax_error(text, end, &line, &col, what, sizeof what);
    return cv_err_set(err, CV_ERR_CONFIG, "%s: line %d, column %d: %s", name, line, col, what);
  }
  ctx x = {name, err};
  int st = parse_root(&x, root, c);
  cJSON_Delete(root);
  return st;
}

int cv_tracker_config_load(const char *path, cv_tracker_config *c, cv_err *err) {
  char *text = NULL;
  size_t n = 0;
  int st = cv_read_text_file(path, &text, &n, err);
  if (st) return st;
  st = cv_tracker_config_parse(text, path, c, err);
  free(text);
  return st;
}

/* ---- the head ------------------------------------------------------------ */

int cv_tracker_head(const cv_tracker_config *c, const cv_dtrack_frame *f, cv_tracked_head *out) {
  for (int k = 0; k < f->n_bodies; k++) {
    if (f->body[k].id != c->body_id) continue;
    if (!(f->body[k].quality > 0)) return CV_ERR_NOT_FOUND;
    /* B (body to room), row-major from DTrack's column-wise b */
    double B[9], M[9];
    for (int r = 0; r < 3; r++)
      for (int col = 0; col < 3; col++) B[3 * r + col] = f->body[k].rot[3 * col + r];
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++)
        M[3 * i + j] = c->room_R[3 * i] * B[j] + c->room_R[3 * i + 1] * B[3 + j] +
                       c->room_R[3 * i + 2] * B[6 + j];
    double p[3], pr[3];
    for (int i = 0; i < 3; i++) p[i] = f->body[k].pos_mm[i] * c->unit_m; /* tracker units */
    mulv(c->room_R, p, pr);
    double off[3], rl[3];
    for (int i = 0; i < 3; i++) out->marker[i] = pr[i] + c->room_T[i];
    mulv(M, c->eye_offset, off);
    mulv(M, c->forward, out->gaze);
    mulv(M, c->up, out->up);
    cross3(c->forward, c->up, rl);
    mulv(M, rl, out->right);
    if (normalise(out->gaze) || normalise(out->up) || normalise(out->right)) return CV_ERR_RANGE;
    for (int i = 0; i < 3; i++) {
      out->center[i] = out->marker[i] + off[i];
      out->eye[0][i] = out->center[i] - 0.5 * c->ipd * out->right[i];
      out->eye[1][i] = out->center[i] + 0.5 * c->ipd * out->right[i];
    }
    const double *g = out->gaze;
    out->yaw_deg = atan2(g[0], -g[2]) * 180.0 / M_PI;
    out->pitch_deg = asin(fmax(-1.0, fmin(1.0, g[1]))) * 180.0 / M_PI;
    /* roll: the up vector against the level up (right = gaze x +Y) */
    double Y[3] = {0, 1, 0}, r0[3], u0[3];
    cross3(g, Y, r0);
    if (normalise(r0)) { /* looking straight up or down: roll is yaw */
      out->roll_deg = 0;
    } else {
      cross3(r0, g, u0);
      out->roll_deg = atan2(dot3(out->up, r0), dot3(out->up, u0)) * 180.0 / M_PI;
    }
    out->quality = f->body[k].quality;
    return CV_OK;
  }
  return CV_ERR_NOT_FOUND;
}

int cv_tracker_open(const cv_tracker_config *c, int port_override, cv_dtrack_receiver **out,
                    cv_err *err) {
  const int port = port_override >= 0 ? port_override : c->port;
  const char *host = c->multicast[0] ? "0.0.0.0" : c->bind;
  int st = cv_dtrack_receiver_open(host, port, c->body_id, out, err);
  if (st || !c->multicast[0]) return st;
  st = cv_dtrack_receiver_join(*out, c->multicast, c->iface[0] ? c->iface : NULL, err);
  if (st) {
    cv_dtrack_receiver_close(*out);
    *out = NULL;
  }
  return st;
}
