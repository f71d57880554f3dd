/* Shared helpers of the `cave` program (see cli.h). */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <libgen.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "cli/cli.h"
#include "core/parse.h"
#include "io/png.h"
#include "io/mesh_import.h"
#include "mesh/cabin.h"
#include "mesh/clean.h"

static int is_light_option(const char *a);

void cli_print_usage(void (*help)(FILE *)) {
  char *buf = NULL;
  size_t n = 0;
  FILE *m = open_memstream(&buf, &n);
  if (!m) {
    help(stderr);
    return;
  }
  help(m);
  fclose(m);
  char *end = strstr(buf, "\n\n"); /* the usage block ends at the first blank line */
  if (end) end[1] = '\0';
  fputs(buf, stderr);
  free(buf);
}

int cli_fail(const char *cmd, int code, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  fprintf(stderr, "cave %s: ", cmd);
  vfprintf(stderr, fmt, ap);
  fputc('\n', stderr);
  va_end(ap);
  return code;
}

int cli_parse_double(const char *s, double *out) { return cv_parse_double(s, out); }
int cli_parse_int(const char *s, int lo, int hi, int *out) { return cv_parse_int(s, lo, hi, out); }
int cli_parse_vec(const char *s, int n, double *out) { return cv_parse_vec(s, n, out); }

int cli_same_file(const char *a, const char *b) {
  struct stat sa, sb;
  if (!strcmp(a, b)) return 1;
  return stat(a, &sa) == 0 && stat(b, &sb) == 0 && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

int cli_check_output(const char *cmd, const char *opt, const char *path) {
  char dir[4096];
  if (!path || !*path) return cli_fail(cmd, 2, "%s: expected a file name, got ''", opt);
  if (strlen(path) >= sizeof dir) return cli_fail(cmd, 2, "%s: path too long", opt);
  struct stat stt;
  if (stat(path, &stt) == 0 && S_ISDIR(stt.st_mode))
    return cli_fail(cmd, 1, "%s: cannot write %s: it is a folder", opt, path);
  snprintf(dir, sizeof dir, "%s", path);
  const char *d = dirname(dir);
  if (stat(d, &stt) != 0)
    return cli_fail(cmd, 1, "%s: cannot write %s: folder %s: %s", opt, path, d, strerror(errno));
  if (!S_ISDIR(stt.st_mode))
    return cli_fail(cmd, 1, "%s: cannot write %s: %s is not a folder", opt, path, d);
  if (access(d, W_OK) != 0)
    return cli_fail(cmd, 1, "%s: cannot write %s: folder %s: %s", opt, path, d, strerror(errno));
  return 0;
}

int cli_parse_size(const char *s, int max, int *w, int *h) {
  /* digits 'x' digits, nothing else: no sign, blank, exponent, fraction or tail */
  long v[2] = {0, 0};
  const char *p = s;
  for (int k = 0; k < 2; k++) {
    if (!p || !isdigit((unsigned char)*p)) return -1;
    for (; isdigit((unsigned char)*p); p++) {
      v[k] = 10 * v[k] + (*p - '0');
      if (v[k] > max) return -1;
    }
    if (k == 0 && *p++ != 'x') return -1;
  }
  if (*p || v[0] < 1 || v[1] < 1) return -1;
  *w = (int)v[0];
  *h = (int)v[1];
  return 0;
}

/* Largest |coordinate| of a camera point, in metres: far beyond any car or
 * CAVE, and well inside what a float ray origin can carry. */
#define CLI_CAMERA_MAX_M 1e6

int cli_check_camera(const char *cmd, const cli_camera_arg *c) {
  const struct {
    const char *name;
    const double *v;
    const char *s;
  } pts[2] = {{"--view", c->eye, c->eye_s}, {"--look", c->look, c->look_s}};
  for (int k = 0; k < 2; k++)
    for (int j = 0; j < 3; j++)
      if (!isfinite(pts[k].v[j]) || fabs(pts[k].v[j]) > CLI_CAMERA_MAX_M)
        return cli_fail(cmd, 2, "%s: expected x,y,z within +-1e6 m, got '%s'", pts[k].name,
                        pts[k].s);
  double f[3], u[3], fl = 0, um = 0, ul = 0;
  for (int j = 0; j < 3; j++) {
    f[j] = c->look[j] - c->eye[j];
    fl += f[j] * f[j];
    um = fmax(um, fabs(c->up[j]));
  }
  fl = sqrt(fl);
  if (!(fl >= 1e-6))
    return cli_fail(cmd, 2, "--look: expected a point other than --view '%s' (the camera looks "
                            "from --view towards --look), got '%s'", c->eye_s, c->look_s);
  if (!(um > 0) || !isfinite(um))
    return cli_fail(cmd, 2, "--view-up: expected a non-zero x,y,z, got '%s'", c->up_s);
  for (int j = 0; j < 3; j++) {
    f[j] /= fl;
    u[j] = c->up[j] / um; /* scaled first: a tiny vector does not underflow */
    ul += u[j] * u[j];
  }
  ul = sqrt(ul);
  double r[3] = {f[1] * u[2] - f[2] * u[1], f[2] * u[0] - f[0] * u[2], f[0] * u[1] - f[1] * u[0]};
  double sin_a = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) / ul;
  if (!(sin_a > 1e-6))
    return cli_fail(cmd, 2, "--view-up: expected a vector not along the view from --view '%s' "
                            "to --look '%s' (looking straight up or down needs e.g. --view-up "
                            "0,0,-1), got '%s'", c->eye_s, c->look_s, c->up_s);
  return 0;
}

int cli_value_missing(const char *cmd, void (*help)(FILE *), const char *a,
                      const char *const *value_opts) {
  int known = is_light_option(a);
  for (int k = 0; !known && value_opts && value_opts[k]; k++) known = !strcmp(a, value_opts[k]);
  if (help) cli_print_usage(help);
  if (known) return cli_fail(cmd, 2, "option '%s' needs a value", a);
  return cli_fail(cmd, 2, "unknown option '%s'", a);
}

int cli_parse_illuminance(const char *s, double *lux) {
  if (s && !strcmp(s, "auto")) {
    *lux = CV_ILLUMINANCE_AUTO;
    return 0;
  }
  double v;
  if (!s || cli_parse_double(s, &v) || !(v > 0) || v > 1e7) return -1;
  *lux = v;
  return 0;
}

int cli_has_ext(const char *path, const char *ext) {
  size_t n = strlen(path), e = strlen(ext);
  return n >= e && strcasecmp(path + n - e, ext) == 0;
}


int cli_place_option(const char *cmd, char **argv, int argc, int *i, cli_place_opts *o,
                     int *rc) {
  const char *a = argv[*i], *v = *i + 1 < argc ? argv[*i + 1] : NULL;
  cv_err e;
  int bit;
  if (!strcmp(a, "--units")) bit = 1;
  else if (!strcmp(a, "--up")) bit = 2;
  else if (!strcmp(a, "--model-scale")) bit = 4;
  else if (!strcmp(a, "--rotate")) bit = 8;
  else if (!strcmp(a, "--translate")) bit = 16;
  else return 0;
  if (!v) {
    *rc = cli_fail(cmd, 2, "%s: missing value", a);
    return -1;
  }
  ++*i;
  int bad = 0;
  if (bit == 1) bad = cv_parse_units(v, &o->p.unit_m, &e) != CV_OK;
  if (bit == 2) bad = cv_parse_up(v, &o->p.up, &e) != CV_OK;
  if (bad) {
    *rc = cli_fail(cmd, 2, "%s: %s", a, e.msg);
    return -1;
  }
  if (bit == 4 && (cli_parse_double(v, &o->p.scale) || !(o->p.scale > 0))) {
    *rc = cli_fail(cmd, 2, "%s: expected a positive number, got '%s'", a, v);
    return -1;
  }
  if ((bit == 8 && cli_parse_vec(v, 3, o->p.rotate_deg)) ||
      (bit == 16 && cli_parse_vec(v, 3, o->p.translate))) {
    *rc = cli_fail(cmd, 2, "%s: expected X,Y,Z (%s), got '%s'", a, bit == 8 ? "degrees" : "metres",
                   v);
    return -1;
  }
  o->given |= bit;
  return 1;
}

int cli_place_apply(const char *cmd, const cli_place_opts *o, cv_scene_config *c) {
  if (!o->given) return 0;
  if (c->mesh_is_cabin)
    return cli_fail(cmd, 2, "--units/--up/--model-scale/--rotate/--translate apply to a mesh "
                            "file, not to the built-in cabin");
  /* each option replaces the config's value */
  if (o->given & 1) c->place.unit_m = o->p.unit_m;
  if (o->given & 2) c->place.up = o->p.up;
  if (o->given & 4) c->place.scale = o->p.scale;
  if (o->given & 8) memcpy(c->place.rotate_deg, o->p.rotate_deg, sizeof o->p.rotate_deg);
  if (o->given & 16) memcpy(c->place.translate, o->p.translate, sizeof o->p.translate);
  return 0;
}





static int is_light_option(const char *a) {
  static const char *const names[] = {"--env", "--weights", "--scale", "--illuminance",
                                      "--env-constant", "--sky", "--yaw", "--pitch", "--roll"};
  for (size_t k = 0; k < sizeof names / sizeof names[0]; k++)
    if (!strcmp(a, names[k])) return 1;
  return 0;
}

static int parse_env_list(const char *cmd, const char *val, cv_light_spec *spec) {
  char buf[8192];
  if (strlen(val) >= sizeof buf) return cli_fail(cmd, 2, "--env: list too long");
  snprintf(buf, sizeof buf, "%s", val);
  cv_err err;
  cv_err_clear(&err);
  /* every field a name: "", ",", "a.exr,,b.exr" are refused (an unset
   * $MAP must not leave an env light without maps) */
  int n = 0;
  for (char *tok = buf;; n++) {
    char *comma = strchr(tok, ',');
    if (comma) *comma = '\0';
    if (!*tok) return cli_fail(cmd, 2, "--env: expected FILE[,FILE...], got '%s'", val);
    if (n == CV_MAX_ENV_MAPS) return cli_fail(cmd, 2, "--env: at most %d maps", CV_MAX_ENV_MAPS);
    if (cv_resolve_env_path(tok, NULL, spec->env[n], &err))
      return cli_fail(cmd, 1, "--env: %s", err.msg);
    if (!comma) break;
    tok = comma + 1;
  }
  spec->kind = CV_LIGHT_ENV;
  spec->n_env = n + 1;
  for (int k = 0; k < spec->n_env; k++) spec->weight[k] = 1.0 / spec->n_env;
  return 0;
}

/* The ranges of the scene config's lighting (src/io/scene_config.c): a
 * radiance, scale or weight above CLI_LIGHT_MAX would overflow a float. */
#define CLI_LIGHT_MAX 1e9

int cli_parse_light(const char *cmd, int argc, char **argv, int *i, cv_light_spec *spec,
                    const char **weights) {
  const char *a = argv[*i], *val = *i + 1 < argc ? argv[*i + 1] : NULL;
  if (!is_light_option(a)) return 0;
  if (!val) return -cli_fail(cmd, 2, "option '%s' needs a value", a);
  ++*i;
  if (!strcmp(a, "--env")) {
    int rc = parse_env_list(cmd, val, spec);
    if (rc) return -rc;
  } else if (!strcmp(a, "--weights")) {
    *weights = val;
  } else if (!strcmp(a, "--scale")) {
    if (cli_parse_double(val, &spec->scale) || spec->scale < 0 || spec->scale > CLI_LIGHT_MAX)
      return -cli_fail(cmd, 2, "--scale: expected a number in [0, 1e9], got '%s'", val);
  } else if (!strcmp(a, "--illuminance")) {
    if (cli_parse_illuminance(val, &spec->illuminance))
      return -cli_fail(cmd, 2, "--illuminance: expected lux (0, 1e7] or auto, got '%s'", val);
  } else if (!strcmp(a, "--env-constant")) {
    spec->kind = CV_LIGHT_CONSTANT;
    const double *c = spec->constant;
    if (cli_parse_vec(val, 3, spec->constant) || c[0] < 0 || c[1] < 0 || c[2] < 0 ||
        c[0] > CLI_LIGHT_MAX || c[1] > CLI_LIGHT_MAX || c[2] > CLI_LIGHT_MAX)
      return -cli_fail(cmd, 2, "--env-constant: expected R,G,B each in [0, 1e9], got '%s'", val);
  } else if (!strcmp(a, "--sky")) {
    double s[3];
    spec->kind = CV_LIGHT_SKY;
    if (cli_parse_vec(val, 3, s) || s[0] < 2 || s[0] > 10 || s[1] < -10 || s[1] > 90 ||
        s[2] < -360 || s[2] > 360)
      return -cli_fail(cmd, 2, "--sky: expected TURBIDITY(2..10),ELEVATION(-10..90),"
                               "AZIMUTH(-360..360), got '%s'", val);
    spec->turbidity = s[0];
    spec->sun_elevation_deg = s[1];
    spec->sun_azimuth_deg = s[2];
  } else {
    double d;
    /* the scene config's car pose ranges (docs/scene-config.md) */
    double lim = !strcmp(a, "--yaw") ? 360 : !strcmp(a, "--pitch") ? 90 : 180;
    if (cli_parse_double(val, &d) || d < -lim || d > lim)
      return -cli_fail(cmd, 2, "%s: expected degrees in [-%g, %g], got '%s'", a, lim, lim, val);
    if (!strcmp(a, "--yaw")) spec->yaw_deg = d;
    else if (!strcmp(a, "--pitch")) spec->pitch_deg = d;
    else spec->roll_deg = d;
  }
  return 1;
}

int cli_apply_weights(const char *cmd, cv_light_spec *spec, const char *weights) {
  if (!weights) return 0;
  if (spec->kind != CV_LIGHT_ENV) return cli_fail(cmd, 2, "--weights needs --env");
  double w[CV_MAX_ENV_MAPS], sum = 0;
  if (cli_parse_vec(weights, spec->n_env, w))
    return cli_fail(cmd, 2, "--weights: expected %d comma-separated numbers, got '%s'", spec->n_env, weights);
  for (int k = 0; k < spec->n_env; k++) {
    if (w[k] < 0 || w[k] > CLI_LIGHT_MAX)
      return cli_fail(cmd, 2, "--weights: expected weights in [0, 1e9], got '%s'", weights);
    spec->weight[k] = w[k];
    sum += w[k];
  }
  if (!(sum > 0)) return cli_fail(cmd, 2, "--weights: the weights sum to 0");
  return 0;
}

/* 1: gnuplot started, its script goes to p->g with output p->of.tmp; 0: no
 * gnuplot installed; -1: failed (err set). */
int cli_plot_begin(cli_plot *p, const char *png, cv_err *err) {
  memset(p, 0, sizeof *p);
  if (system("command -v gnuplot >/dev/null 2>&1") != 0) return 0;
  if (cv_outfile_open(&p->of, png, 0, err) != CV_OK) return -1;
  close(p->of.fd); /* gnuplot opens it by name */
  p->of.fd = -1;
  p->g = popen("gnuplot", "w");
  if (!p->g) {
    int e = errno;
    cv_outfile_abort(&p->of);
    cv_err_set(err, CV_ERR_IO, "%s: cannot start gnuplot: %s", png, strerror(e));
    return -1;
  }
  return 1;
}

/* Ends gnuplot; the plot gets its name only when gnuplot succeeded and the
 * PNG decodes whole.  1 when written, -1 (err set, nothing left) if not. */
int cli_plot_end(cli_plot *p, const char *png, cv_err *err) {
  const int st = pclose(p->g);
  p->g = NULL;
  cv_image *im = NULL;
  cv_err e2;
  cv_err_clear(&e2);
  struct stat sb;
  const long long bytes = stat(p->of.tmp, &sb) == 0 ? (long long)sb.st_size : -1;
  const int whole = st == 0 && cv_png_read(p->of.tmp, &im, &e2) == CV_OK;
  cv_image_destroy(im);
  if (!whole) {
    struct statvfs fs;
    const double free_kb = statvfs(p->of.tmp, &fs) == 0 ? (double)fs.f_bavail * (double)fs.f_frsize / 1024.0 : -1;
    cv_outfile_abort(&p->of);
    cv_err_set(err, CV_ERR_IO, "%s: not written: gnuplot %s (%lld bytes; %.0f KB free on its disk)", png,
               st != 0 ? "failed" : "wrote a cut-short or unreadable PNG", bytes, free_kb);
    return -1;
  }
  return cv_outfile_commit(&p->of, err) == CV_OK ? 1 : -1;
}
