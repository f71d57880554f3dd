/* cave plot: PNG plots of a whole run from its metrics.jsonl (docs/metrics.md
 * "Plots"): frame time, swap skew, motion-to-photon latency, and each LCD
 * panel's contrast ratio with the 3:1 line.  A file named X.jsonl is read
 * with its rotated set (X.N.jsonl .. X.1.jsonl first, oldest first).  The
 * PNGs are drawn by gnuplot (Debian gnuplot-nox), each under a temporary
 * name and renamed only when gnuplot succeeded and the PNG decodes whole. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cjson/cJSON.h>

#include "cli/cli.h"
#include "core/status.h"
#include "service/index_html.h"

#define PLOT_PANELS 16

typedef struct plot_row {
  double frame, t, frame_ms, master_ms, skew_us, mtp_ms, age_ms;
  double cr[PLOT_PANELS];
} plot_row;

typedef struct plot_data {
  plot_row *rows;
  size_t n, cap;
  char panel[PLOT_PANELS][64];
  int n_panels;
  double cr_min;
  double last_frame;
  char first_file[1024];
  int n_files;
} plot_data;

static void plot_help(FILE *f) {
  fprintf(f,
          "usage: cave plot FILE... -o DIR [--index RUNDIR] [--quiet]\n\n"
          "PNG plots of a `cave run` from its metrics lines (docs/metrics.md \"Plots\"):\n"
          "  DIR/frame_time.png   frame time and the master's own time per frame (ms)\n"
          "  DIR/swap_skew.png    swap skew between the wall-eyes per frame (us)\n"
          "  DIR/latency.png      motion-to-photon latency and tracker age at the swap (ms)\n"
          "  DIR/readability.png  each LCD panel's mean contrast ratio per frame, with\n"
          "                       the requirement (cr_min, 3:1) as a line\n"
          "A plot whose series no frame line has (e.g. readability with --no-lcd) is\n"
          "not written, and a line says so.  FILE named X.jsonl is read with its\n"
          "rotated files X.N.jsonl .. X.1.jsonl before it (--metrics-max-mb), oldest\n"
          "first; several FILEs are read in the order given, and their frame numbers\n"
          "must increase.  Needs gnuplot (Debian gnuplot-nox).\n\n"
          "  -o DIR          output folder (created when missing)\n"
          "  --index RUNDIR  afterwards (re)write RUNDIR/index.html: the newest montages\n"
          "                  of each variant, lcd.png and the plots in RUNDIR/plots\n"
          "  --quiet         no lines for the PNGs written\n\n"
          "examples:\n"
          "  cave plot out/run/metrics.jsonl -o out/run/plots --index out/run\n");
}

static double num_at(const cJSON *o, const char *a, const char *b) {
  const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, a);
  if (b) x = cJSON_GetObjectItemCaseSensitive(x, b);
  return cJSON_IsNumber(x) ? x->valuedouble : NAN;
}

/* The panels' contrast ratios of a frame line (lcd.readability.panels). */
static void row_panels(plot_data *d, const cJSON *line, plot_row *r) {
  const cJSON *rd = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(line, "lcd"), "readability");
  if (!rd) return;
  const double cm = num_at(rd, "cr_min", NULL);
  if (isfinite(cm)) d->cr_min = cm;
  const cJSON *p;
  cJSON_ArrayForEach(p, cJSON_GetObjectItemCaseSensitive(rd, "panels")) {
    int k = 0;
    while (k < d->n_panels && strcmp(d->panel[k], p->string)) k++;
    if (k == d->n_panels) {
      if (k == PLOT_PANELS) continue;
      snprintf(d->panel[k], sizeof d->panel[k], "%s", p->string);
      d->n_panels++;
    }
    r->cr[k] = num_at(p, "contrast_ratio", NULL);
  }
}

/* One metrics line: frame lines become rows; others are skipped. */
static int take_line(plot_data *d, const char *file, long ln, const char *text, int cut) {
  cJSON *o = cJSON_Parse(text);
  if (!o || !cJSON_IsObject(o)) {
    cJSON_Delete(o);
    return cli_fail("plot", 1, "%s line %ld: %s", file, ln,
                    cut ? "cut short (no newline at the end: is the file being written?)"
                        : "not a JSON object (expected one metrics line per line)");
  }
  const cJSON *ty = cJSON_GetObjectItemCaseSensitive(o, "type");
  if (!cJSON_IsString(ty)) {
    cJSON_Delete(o);
    return cli_fail("plot", 1, "%s line %ld: no \"type\" (not a cave run metrics line)", file, ln);
  }
  int rc = 0;
  if (!strcmp(ty->valuestring, "frame")) {
    plot_row r;
    memset(&r, 0, sizeof r);
    for (int k = 0; k < PLOT_PANELS; k++) r.cr[k] = NAN;
    r.frame = num_at(o, "frame", NULL);
    r.t = num_at(o, "t", NULL);
    r.frame_ms = num_at(o, "frame_ms", NULL);
    r.master_ms = num_at(o, "master_ms", NULL);
    r.skew_us = num_at(o, "sync", "swap_skew_us");
    r.mtp_ms = num_at(o, "sync", "motion_to_photon_ms");
    r.age_ms = num_at(o, "sync", "tracker_age_at_swap_ms");
    row_panels(d, o, &r);
    if (!isfinite(r.frame)) {
      rc = cli_fail("plot", 1, "%s line %ld: a frame line without a \"frame\" number", file, ln);
    } else if (d->n && !(r.frame > d->last_frame)) {
      rc = cli_fail("plot", 1, "%s line %ld: frame %.0f after frame %.0f: the files are out of order, or one "
                    "run's file was given twice", file, ln, r.frame, d->last_frame);
    } else if (d->n == d->cap) {
      d->cap = d->cap ? 2 * d->cap : 1024;
      plot_row *nr = realloc(d->rows, d->cap * sizeof *nr);
      if (!nr) rc = cli_fail("plot", 1, "out of memory");
      else d->rows = nr;
    }
    if (!rc) {
      d->rows[d->n++] = r;
      d->last_frame = r.frame;
    }
  }
  cJSON_Delete(o);
  return rc;
}

static int read_file(plot_data *d, const char *file) {
  FILE *f = fopen(file, "r");
  if (!f) return cli_fail("plot", 1, "%s: cannot read: %s", file, strerror(errno));
  d->n_files++;
  char *line = NULL;
  size_t cap = 0;
  ssize_t len;
  long ln = 0;
  int rc = 0;
  while (!rc && (len = getline(&line, &cap, f)) >= 0) {
    ln++;
    const int cut = len == 0 || line[len - 1] != '\n';
    if (!cut) line[len - 1] = 0;
    if (line[0]) rc = take_line(d, file, ln, line, cut);
  }
  if (!rc && ferror(f)) rc = cli_fail("plot", 1, "%s: read failed: %s", file, strerror(errno));
  free(line);
  fclose(f);
  return rc;
}

/* FILE and, for X.jsonl, its rotated X.N.jsonl .. X.1.jsonl first. */
static int read_set(plot_data *d, const char *file) {
  const size_t n = strlen(file);
  if (!d->first_file[0]) snprintf(d->first_file, sizeof d->first_file, "%s", file); /* the plots' titles name it */
  if (n > 6 && !strcmp(file + n - 6, ".jsonl")) {
    char r[4200];
    struct stat st;
    int top = 0;
    for (int k = 1; k <= 1000; k++) {
      snprintf(r, sizeof r, "%.*s.%d.jsonl", (int)(n - 6), file, k);
      if (stat(r, &st) != 0) break;
      top = k;
    }
    for (int k = top; k >= 1; k--) {
      snprintf(r, sizeof r, "%.*s.%d.jsonl", (int)(n - 6), file, k);
      int rc = read_file(d, r);
      if (rc) return rc;
    }
  }
  return read_file(d, file);
}

/* The rows as a gnuplot datablock $d: frame, t, frame_ms, master_ms,
 * skew_us, mtp_ms, age_ms, cr[0..n_panels); "?" missing. */
static void put_data(FILE *g, const plot_data *d) {
  fprintf(g, "set datafile missing '?'\n$d << EOD\n");
  for (size_t i = 0; i < d->n; i++) {
    const plot_row *r = &d->rows[i];
    const double v[7] = {r->frame, r->t, r->frame_ms, r->master_ms, r->skew_us, r->mtp_ms, r->age_ms};
    for (int k = 0; k < 7 + d->n_panels; k++) {
      const double x = k < 7 ? v[k] : r->cr[k - 7];
      if (isfinite(x)) fprintf(g, "%s%.9g", k ? " " : "", x);
      else fprintf(g, "%s?", k ? " " : "");
    }
    fputc('\n', g);
  }
  fprintf(g, "EOD\n");
}

static int has(const plot_data *d, int col) {
  for (size_t i = 0; i < d->n; i++) {
    const plot_row *r = &d->rows[i];
    const double v[7] = {r->frame, r->t, r->frame_ms, r->master_ms, r->skew_us, r->mtp_ms, r->age_ms};
    if (isfinite(col < 7 ? v[col] : r->cr[col - 7])) return 1;
  }
  return 0;
}

/* gnuplot text: the name with quotes and underscores made harmless. */
static void safe(char *out, size_t cap, const char *s) {
  size_t j = 0;
  for (; *s && j + 1 < cap; s++) out[j++] = (*s == '\'' || *s == '"' || *s == '\\') ? ' ' : *s;
  out[j] = 0;
}

/* One plot; its gnuplot commands after the data: what (title), ylabel and
 * the plot line.  1 written, -1 failed. */
static int plot_one(const plot_data *d, const char *dir, const char *name, const char *title, const char *ylabel,
                    const char *extra, const char *plot, int quiet) {
  char png[4200], src[1100];
  snprintf(png, sizeof png, "%s/%s", dir, name);
  safe(src, sizeof src, d->first_file);
  cli_plot po;
  cv_err err;
  cv_err_clear(&err);
  const int b = cli_plot_begin(&po, png, &err);
  if (b <= 0) {
    if (b == 0) cli_fail("plot", 1, "%s: gnuplot is not installed (Debian package gnuplot-nox; cluster/setup.sh installs it)", png);
    else cli_fail("plot", 1, "%s", err.msg);
    return -1;
  }
  FILE *g = po.g;
  fprintf(g, "set terminal pngcairo size 1100,500 font ',11' noenhanced\nset output '%s'\n", po.of.tmp);
  put_data(g, d);
  fprintf(g, "set title '%s (%zu frame lines, frames %.0f..%.0f of %s%s)'\n", title, d->n, d->rows[0].frame,
          d->rows[d->n - 1].frame, src, d->n_files > 1 ? " and the files before it" : "");
  fprintf(g, "set xlabel 'frame'\nset ylabel '%s'\nset grid\nset key top right box opaque\n", ylabel);
  if (d->rows[d->n - 1].frame > d->rows[0].frame) fprintf(g, "set xrange [%.0f:%.0f]\n", d->rows[0].frame, d->rows[d->n - 1].frame);
  fprintf(g, "%s\n%s\n", extra ? extra : "", plot);
  if (cli_plot_end(&po, png, &err) < 0) {
    cli_fail("plot", 1, "%s", err.msg);
    return -1;
  }
  if (!quiet) printf("wrote %s\n", png);
  return 1;
}

static int plot_readability(const plot_data *d, const char *dir, int quiet) {
  char plot[8192], nm[80];
  size_t l = (size_t)snprintf(plot, sizeof plot, "plot ");
  for (int k = 0; k < d->n_panels; k++) {
    safe(nm, sizeof nm, d->panel[k]);
    l += (size_t)snprintf(plot + l, sizeof plot - l, "$d using 1:%d with linespoints pt 7 ps 0.5 lw 2 title 'panel %s', ",
                          8 + k, nm);
  }
  const double cm = d->cr_min > 0 ? d->cr_min : 3;
  snprintf(plot + l, sizeof plot - l, "%g with lines lw 2 dt 2 lc rgb 'red' title 'requirement %g:1 (cr_min)'", cm, cm);
  char extra[200];
  snprintf(extra, sizeof extra, "set logscale y\nset yrange [0.9:*]\nset ytics (1,%g,2,3,5,10,20,50,100,200,500,1000)\nset key bottom right box opaque", cm);
  return plot_one(d, dir, "readability.png", "LCD readability: mean contrast ratio per panel",
                  "contrast ratio (log scale)", extra, plot, quiet);
}

static int plot_all(const plot_data *d, const char *dir, int quiet) {
  int rc = 0;
  if (plot_one(d, dir, "frame_time.png", "Frame time", "time per frame (ms)", "set yrange [0:*]",
               "plot $d using 1:3 with lines lw 2 title 'frame time (frame_ms)', "
               "$d using 1:4 with lines lw 1 title 'master own work (master_ms)'",
               quiet) < 0)
    return 1;
  if (!has(d, 4)) printf("swap_skew.png: not written: no frame line has sync.swap_skew_us\n");
  else if (plot_one(d, dir, "swap_skew.png", "Swap skew between the wall-eyes", "skew (microseconds)",
                    "set yrange [0:*]", "plot $d using 1:5 with linespoints pt 7 ps 0.4 lw 2 title 'swap skew (sync.swap_skew_us)'",
                    quiet) < 0)
    rc = 1;
  if (!has(d, 5)) printf("latency.png: not written: no frame line has sync.motion_to_photon_ms\n");
  else if (plot_one(d, dir, "latency.png", "Motion-to-photon latency", "latency (ms)", "set yrange [0:*]",
                    "plot $d using 1:6 with linespoints pt 7 ps 0.4 lw 2 title 'motion to photon (sync.motion_to_photon_ms)', "
                    "$d using 1:7 with lines lw 1 title 'tracker age at the swap (sync.tracker_age_at_swap_ms)'",
                    quiet) < 0)
    rc = 1;
  int any_cr = 0;
  for (int k = 0; k < d->n_panels; k++) any_cr |= has(d, 7 + k);
  if (!any_cr) printf("readability.png: not written: no frame line has lcd.readability (--no-lcd, or no LCD round yet)\n");
  else if (plot_readability(d, dir, quiet) < 0)
    rc = 1;
  return rc;
}

static int ensure_dir(const char *dir) {
  struct stat st;
  if (stat(dir, &st) == 0) return S_ISDIR(st.st_mode) ? 0 : cli_fail("plot", 2, "-o: %s: is a file, expected a folder", dir);
  if (mkdir(dir, 0777) != 0) return cli_fail("plot", 1, "-o: cannot create %s: %s", dir, strerror(errno));
  return 0;
}

int cmd_plot(int argc, char **argv) {
  const char *files[256], *dir = NULL, *index = NULL;
  int nf = 0, quiet = 0;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      plot_help(stdout);
      return 0;
    } else if (!strcmp(a, "-o") || !strcmp(a, "--index")) {
      if (i + 1 >= argc) return cli_value_missing("plot", plot_help, a, (const char *const[]){"-o", "--index", NULL});
      if (!strcmp(a, "-o")) dir = argv[++i];
      else index = argv[++i];
    } else if (!strcmp(a, "--quiet")) {
      quiet = 1;
    } else if (a[0] == '-' && a[1]) {
      cli_print_usage(plot_help);
      return cli_fail("plot", 2, "unknown option '%s'", a);
    } else if (nf < 256) {
      files[nf++] = a;
    } else {
      return cli_fail("plot", 2, "more than 256 files");
    }
  }
  if (!nf || !dir) {
    cli_print_usage(plot_help);
    return cli_fail("plot", 2, "%s", !nf ? "expected a metrics file (FILE...)" : "expected -o DIR");
  }
  plot_data d;
  memset(&d, 0, sizeof d);
  int rc = 0;
  for (int i = 0; i < nf && !rc; i++) rc = read_set(&d, files[i]);
  if (!rc && !d.n) rc = cli_fail("plot", 1, "%s: no frame lines (\"type\": \"frame\") to plot", files[0]);
  if (!rc && !quiet) printf("read %zu frame lines from %d files\n", d.n, d.n_files);
  if (!rc) rc = ensure_dir(dir);
  if (!rc) rc = plot_all(&d, dir, quiet);
  if (!rc && index) {
    cv_err err;
    if (cv_index_html_write(index, &err) != CV_OK) rc = cli_fail("plot", 1, "--index: %s", err.msg);
    else if (!quiet) printf("wrote %s/index.html\n", index);
  }
  free(d.rows);
  return rc;
}
