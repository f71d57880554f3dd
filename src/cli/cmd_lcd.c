/* `cave lcd`: what the driver sees on the dashboard LCD panel under the
 * current daylight from the tracked head position (Dmitriev et al. 2004,
 * section 4.3): the panel's emitted content plus its reflection of the car
 * interior (PRT radiance) and the sky through the windows, final-gathered
 * with one bounce through a tabulated BRDF, progressively in fixed point
 * (src/lcd).  Writes the panel image (EXR), a sidecar JSON with its sample
 * count, error estimate and readability figures (lcd/readability.h), a
 * contrast-ratio heat map PNG, and optionally a tone-mapped PNG. */
#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "cli/cli.h"
#include "core/parse.h"
#include "core/outfile.h"
#include "core/progress.h"
#include "io/exr.h"
#include "io/png.h"
#include "io/tonemap_simple.h"
#include "lcd/gather.h"
#include "lcd/heatmap.h"
#include "lcd/lcd_config.h"
#include "lcd/light_level.h"
#include "lcd/panels.h"
#include "lcd/readability.h"
#include "lcd/sweep.h"
#include "prt/bake.h"
#include "prt/scene_light.h"
#include "service/drive.h"
#include "service/tracker.h"
#include "view/cave.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave lcd <scene.prt | scene.json> --eye x,y,z LIGHT [--yaw DEG] [--pitch DEG]\n"
          "                [--roll DEG] [--spp N] [--rounds R] [--size WxH] [--brdf FILE]\n"
          "                [--sampling brdf|cosine|mis] [--content FILE] [--luminance CD] [--seed S]\n"
          "                [--lcd-config FILE] [--prt FILE] [--threads N] [--black CD] [--cr-min R]\n"
          "                [--age YEARS] [--pigment P] [--adaptation CD] [--glare-spc N] [--area-min S]\n"
          "                [--vl-min V] [--heatmap FILE.png] -o panel.exr [--png]\n"
          "       cave lcd <scene.prt | scene.json> --drive DRIVE.json (--head-path FILE | --eye x,y,z)\n"
          "                [--cave CAVE.json | --scene-offset x,y,z] [--dt S] [options] -o series.csv\n"
          "       cave lcd SCENE --eye x,y,z LIGHT --illuminance-sweep LO:HI[:N] [options] -o sweep.csv\n\n"
          "Final gather on the LCD panel (the scene's triangles tagged lcd): for every texel the\n"
          "eye ray from --eye gives the view direction; reflected rays are drawn from the\n"
          "panel's BRDF and traced one bounce: through a window they read the environment,\n"
          "elsewhere the PRT radiance of the hit triangle; the sun is added where it reaches the\n"
          "panel.  The panel's content (--content image, --luminance cd/m^2 for white) is added.\n"
          "Rounds of --spp samples per texel accumulate in fixed point (same result for any split).\n\n"
          "LIGHT is one of --env FILE[,FILE...] [--weights w,..] [--scale S |\n"
          "--illuminance LUX|auto] [--no-sun],\n"
          "--env-constant R,G,B, --sky TURBIDITY,ELEVATION,AZIMUTH (as cave shade); a\n"
          "scene.json's own lighting is used when none is given.\n\n"
          "  --eye x,y,z       driver's eye, car frame, metres (quantised by lcd.eye_tolerance);\n"
          "                    inside the scene's bounding box (+ 5 cm) and in front of every panel\n"
          "  --spp N           samples per texel per round (default 40)\n"
          "  --rounds R        rounds (default 1)\n"
          "  --size WxH        panel texels (default 400 wide, height from the panel's aspect)\n"
          "  --brdf FILE       BRDF table (docs/brdf-format.md), MERL .binary, or\n"
          "                    builtin:antiglare (default)\n"
          "  --sampling S      brdf, cosine, or mis (default: mis: half of the samples from\n"
          "                    the environment map by luminance x window visibility x BRDF,\n"
          "                    the rest 90%% BRDF / 10%% cosine; the sun by next-event\n"
          "                    estimation in all three)\n"
          "  --content FILE    .png (sRGB) or .exr shown on the panel (default: a test pattern)\n"
          "  --luminance CD    content white luminance in cd/m^2, 0..1e6 (default 500)\n"
          "  --lcd-config FILE JSON {\"lcd\": {...}} with these settings (docs/scene-config.md);\n"
          "                    a scene.json's own \"lcd\" block is read first; --size, --brdf,\n"
          "                    --content, --luminance and --black override the block and\n"
          "                    every panel's own value\n"
          "  --seed S          sample sequence seed, 0..4294967295 (default lcd.seed: 1)\n"
          "  --prt FILE        with a scene.json: the baked PRT to use (else baked here)\n"
          "                    (a scene.prt alone: the lcd block `cave bake` wrote next to it,\n"
          "                    scene.prt.lcd.json, gives the panels; without one, one default panel)\n"
          "  --png             also write a tone-mapped PNG next to the EXR\n"
          "Readability (docs/readability.md; each figure with its standard error):\n"
          "  --black CD        panel black luminance in cd/m^2, 0..1e6 (default 0.002 x white)\n"
          "  --cr-min R        required contrast ratio, 1..1000 (default 3, ISO 15008)\n"
          "  --age YEARS       driver's age for the CIE 146 disability glare (default 40)\n"
          "  --pigment P       eye pigmentation 0 (dark) .. 1 (light blue) (default 0.5)\n"
          "  --glare-spc N     samples per cell of the 48 x 96 glare integral (even, default 4)\n"
          "  --adaptation CD   adaptation luminance for the visibility level, 0..1e6 (default: the\n"
          "                    panel background seen, black + reflection + veil)\n"
          "  --heatmap FILE    contrast-ratio heat map PNG (default panel.cr.png)\n"
          "  --area-min S      verdict: share of the panel area that must meet --cr-min, 0..1\n"
          "                    (default 0.95)\n"
          "  --vl-min V        verdict: smallest visibility level, 0..1e6 (default 5)\n"
          "Absolute light or no verdict: READABLE / UNREADABLE (CR, area share and VL all\n"
          "pass) only when the light is absolute: --illuminance LUX (auto: an ASSUMED level of a\n"
          "blender-data map), --sky, --env-constant (taken as cd/m^2), or a scene or drive\n"
          "config's \"illuminance\" or \"absolute\": true.  A map in its own units is marked\n"
          "uncalibrated everywhere and gets no verdict.  The illuminance outdoors and at the eye\n"
          "(horizontal, vertical facing ahead) and its source are printed and in the sidecar.\n"
          "  --illuminance-sweep LO:HI[:N]  the figures at N levels (default 21, log spaced) of\n"
          "                    the outdoor horizontal illuminance LO..HI lux (0 < LO < HI <= 1e7,\n"
          "                    N 2..1000) from one render (the light's shape and the sun's\n"
          "                    position as given, its level scaled): sweep.csv, sweep.png, and\n"
          "                    per panel the lux where the mean CR falls to --cr-min\n"
          "A whole drive, offline (no MPI):\n"
          "  --drive FILE      drive file (configs/drives/): lighting and car attitude over time\n"
          "  --head-path FILE  recorded head path (t x y z gx gy gz, CAVE frame); the eye is\n"
          "                    head + scene offset (default that of configs/caves/cave5.json)\n"
          "  --cave FILE       take the scene offset from a CAVE config\n"
          "  --scene-offset V  scene point = CAVE point + V (metres)\n"
          "  --dt S            seconds between steps, 0.5 or 1/2 (default 0.5); each step renders --rounds\n"
          "                    rounds and writes one CSV row (docs/readability.md), and\n"
          "                    series.png is plotted with gnuplot when it is installed\n"
          "Outputs: panel.exr (linear RGB radiance), panel.exr.json (samples, error estimate,\n"
          "readability), panel.cr.png (CR over the panel, white contour at the requirement,\n"
          "colour bar CR 1..10 on a log scale below with the requirement marked white).\n"
          "Several panels (the scene config's lcd.panels, docs/scene-config.md): figures per\n"
          "panel, and panel.<name>.exr, .exr.json, .cr.png per panel; --drive: 13 CSV columns\n"
          "per panel prefixed <name>.  `cave run --scene-config` uses the same model.\n"
          "\nexamples:\n"
          "  cave lcd scene.prt --eye -0.37,1.1,0.3 --env forest.exr --illuminance auto -o panel.exr --png\n"
          "  cave lcd configs/scenes/default.json --eye -0.37,1.1,0.3 --rounds 4 -o panel.exr\n"
          "  cave lcd scene.prt --eye -0.37,1.02,0 --sky 3,20,180 --illuminance-sweep 1000:200000 -o sweep.csv\n");
}

/* s as a JSON string (quotes, backslashes and control characters escaped). */
static void json_str(FILE *f, const char *s) {
  fputc('"', f);
  for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
    if (*c == '"' || *c == '\\') fprintf(f, "\\%c", *c);
    else if (*c < 0x20) fprintf(f, "\\u%04x", *c);
    else fputc(*c, f);
  }
  fputc('"', f);
}

/* What the light level is (light_level.h) and the verdict: the sidecar's
 * "light" block and the readability block's first fields. */
typedef struct lcd_light_info {
  cv_lcd_calib cal;
  cv_lcd_illum il;
} lcd_light_info;

static void sidecar_light(FILE *f, const lcd_light_info *li) {
  fprintf(f, "  \"light\": {\"absolute\": %s, \"assumed\": %s, \"source\": ",
          li->cal.absolute ? "true" : "false", li->cal.assumed ? "true" : "false");
  json_str(f, li->cal.source);
  fprintf(f,
          ",\n    \"unit\": \"%s\", \"outdoor_horizontal_illuminance\": %.6g,\n"
          "    \"eye_horizontal_illuminance\": %.6g, \"eye_horizontal_illuminance_se\": %.3g,\n"
          "    \"eye_vertical_illuminance\": %.6g, \"eye_vertical_illuminance_se\": %.3g},\n",
          li->cal.absolute ? "lx" : "relative", li->il.outdoor_h, li->il.eye_h, li->il.eye_h_se,
          li->il.eye_v, li->il.eye_v_se);
}

static int write_sidecar(const char *path, const cv_lcd_accum *acc, const cv_lcd_error *e,
                         const cv_lcd_key *key, double seconds, const char *brdf,
                         const cv_lcd_readability *rd, const cv_lcd_read_params *rp,
                         const cv_lcd_veil_params *vp, const lcd_light_info *li, cv_err *err) {
  cv_outfile o;
  int st = cv_outfile_open(&o, path, 1, err);
  if (st) return st;
  char why[160];
  const cv_lcd_verdict_kind v = cv_lcd_verdict(rd, rp, li->cal.absolute, why, sizeof why);
  const int64_t *d = acc->data;
  fprintf(o.f,
          "{\n  \"width\": %d, \"height\": %d,\n  \"samples_per_texel\": %lld, \"rounds\": %lld,\n"
          "  \"estimated_relative_rms_error\": %.6g,\n  \"mean_reflected_luminance\": %.6g,\n"
          "  \"clamped_values\": %lld, \"nonfinite_values\": %lld,\n"
          "  \"rays\": {\"interior\": %lld, \"environment\": %lld, \"lost\": %lld, \"sun_shadow\": %lld, \"sun_unblocked\": %lld},\n"
          "  \"key\": {\"eye_q\": [%d, %d, %d], \"light_hash\": \"%016llx\", \"setup_hash\": \"%016llx\"},\n"
          "  \"brdf\": \"%s\", \"seconds\": %.3f,\n",
          acc->w, acc->h, (long long)d[CV_LCD_ACC_SPP], (long long)d[CV_LCD_ACC_ROUNDS], e->rel_rms,
          e->mean_luminance, (long long)d[CV_LCD_ACC_CLAMPED], (long long)d[CV_LCD_ACC_NONFINITE],
          (long long)d[CV_LCD_ACC_HITS], (long long)d[CV_LCD_ACC_ENV], (long long)d[CV_LCD_ACC_LOST],
          (long long)d[CV_LCD_ACC_SHADOW], (long long)d[CV_LCD_ACC_SUNLIT], key->eye_q[0],
          key->eye_q[1], key->eye_q[2], (unsigned long long)key->light_hash,
          (unsigned long long)key->setup_hash, brdf, seconds);
  sidecar_light(o.f, li);
  fprintf(o.f, "  \"readability\": {\"calibrated\": %s, \"verdict\": \"%s\", \"verdict_reason\": ",
          li->cal.absolute ? "true" : "false", cv_lcd_verdict_name(v));
  json_str(o.f, why);
  fprintf(o.f, ",\n    \"area_min\": %.6g, \"vl_min\": %.6g,\n", rp->area_min, rp->vl_min);
  fprintf(o.f,
          "    \"white_luminance\": %.6g, \"black_luminance\": %.6g, \"cr_min\": %.6g,\n"
          "    \"age\": %.6g, \"pigment\": %.6g,\n"
          "    \"contrast_ratio\": %.6g, \"contrast_ratio_se\": %.3g, \"contrast_ratio_worst\": %.6g,\n"
          "    \"area_meeting_cr_min\": %.6g, \"area_meeting_cr_min_se\": %.3g,\n"
          "    \"reflected_luminance\": %.6g, \"reflected_luminance_se\": %.3g,\n"
          "    \"veiling_luminance\": %.6g, \"veiling_luminance_se\": %.3g,\n"
          "    \"adaptation_luminance\": %.6g, \"threshold_difference\": %.6g,\n"
          "    \"visibility_level\": %.6g, \"visibility_level_se\": %.3g}\n}\n",
          rp->white, rp->black, rp->cr_min, vp->age, vp->pigment, rd->cr_mean.value,
          rd->cr_mean.se, rd->cr_worst, rd->frac_ok.value, rd->frac_ok.se, rd->L_r.value,
          rd->L_r.se, rd->L_v.value, rd->L_v.se, rd->L_a.value, rd->dL_threshold, rd->vl.value,
          rd->vl.se);
  return cv_outfile_commit(&o, err);
}

/* Writes the CR heat map figure (lcd/heatmap.h): the panel's name, figures
 * and verdict, and the light level in the title. */
static int write_heatmap(const char *path, const cv_lcd_readability *rd, const char *name,
                         const cv_lcd_read_params *q, const lcd_light_info *li, cv_err *err) {
  char l[CV_LCD_HEATMAP_LINES][200], why[160];
  const cv_lcd_verdict_kind v = cv_lcd_verdict(rd, q, li->cal.absolute, why, sizeof why);
  snprintf(l[0], sizeof l[0], "panel %s: CR %.3g +- %.2g; %.1f%% of the area meets %g:1; VL %.3g",
           name, rd->cr_mean.value, rd->cr_mean.se, 100 * rd->frac_ok.value, q->cr_min, rd->vl.value);
  if (v == CV_LCD_UNCALIBRATED) snprintf(l[1], sizeof l[1], "no verdict: uncalibrated light");
  else snprintf(l[1], sizeof l[1], "%s: %s%s", cv_lcd_verdict_name(v), why,
                li->cal.assumed ? " (assumed light level)" : "");
  if (li->cal.absolute)
    snprintf(l[2], sizeof l[2], "light %.0f lx outdoors (horizontal); at the eye %.0f lx horizontal, "
             "%.0f lx vertical", li->il.outdoor_h, li->il.eye_h, li->il.eye_v);
  else
    snprintf(l[2], sizeof l[2], "light UNCALIBRATED: relative units (outdoors %.3g): no verdict",
             li->il.outdoor_h);
  snprintf(l[3], sizeof l[3], "%.119s", li->cal.source);
  const char *lines[CV_LCD_HEATMAP_LINES] = {l[0], l[1], l[2], l[3]};
  uint8_t *px = NULL;
  int W, H;
  int st = cv_lcd_heatmap_figure(rd, lines, CV_LCD_HEATMAP_LINES, &px, &W, &H);
  if (st) return cv_err_set(err, st, "%s: %s", path, cv_status_str(st));
  st = cv_png_write(path, W, H, 3, px, err);
  free(px);
  return st;
}

/* --- a whole drive, offline ------------------------------------------------ */

typedef struct drive_job {
  const char *drive_path, *head_path, *csv;
  double offset[3]; /* scene point = CAVE point + offset (head path -> car frame) */
  double eye[3];    /* the eye when there is no head path */
  double dt;        /* seconds between steps */
} drive_job;

/* Writes the plot PNG of a drive CSV with gnuplot (when it is installed):
 * CR with its error bars against time, the requirement as a line, the steps
 * below it marked.  Returns 1 when written, 0 without gnuplot, -1 on failure
 * (err set). */
static int drive_plot(const char *csv, const char *png, double cr_min, const cv_lcd_config *lc,
                      int absolute, cv_err *err) {
  cli_plot po;
  const int b = cli_plot_begin(&po, png, err);
  if (b <= 0) return b;
  FILE *g = po.g;
  fprintf(g,
          "set terminal pngcairo size 1000,450 font ',10'\n"
          "set output '%s'\n"
          "set datafile separator ','\n"
          "set key top right\n"
          "set xlabel 'drive time (s)'\nset ylabel 'contrast ratio'\nset grid\n"
          "set title \"LCD readability over the drive: CR +- 1 s.e.; below the line the panel "
          "misses the required %g:1 (ISO 15008)%s\"\n"
          "plot ",
          po.of.tmp, cr_min,
          absolute ? "" : "\\nUNCALIBRATED light (relative units): no verdict, CR not comparable with 3:1");
  static const char *const col[CV_LCD_MAX_PANELS] = {"#3b528b", "#21918c", "#5ec962", "#440154"};
  for (int i = 0; i < lc->n_panels; i++) {
    const int c = 11 + 13 * i; /* the panel's CR column (1-based), its s.e. next, readable c + 7 */
    fprintf(g,
            "'%s' using 1:%d:%d with yerrorbars lc rgb '%s' pt 7 ps 0.6 title 'CR %s', "
            "'' using 1:%d with lines lc rgb '%s' notitle, "
            "'' using 1:($%d == 0 ? $%d : 1/0) with points pt 7 ps 1.2 lc rgb '#d62728' %s, ",
            csv, c, c + 1, col[i], lc->panels[i].name, c, col[i], c + 7, c,
            i == 0 ? "title 'UNREADABLE (CR, area or VL)'" : "notitle");
  }
  fprintf(g, "%g with lines dt 2 lw 2 lc rgb '#d62728' title 'required %g:1'\n", cr_min, cr_min);
  return cli_plot_end(&po, png, err);
}

/* Readability parameters of panel i: the block's, with the panel's white and
 * black. */
static cv_lcd_read_params panel_rp(const cv_lcd_read_params *rp, const cv_lcd_config *lc, int i) {
  cv_lcd_read_params q = *rp;
  q.white = lc->panels[i].content_luminance;
  q.black = lc->panels[i].black_luminance;
  return q;
}

/* Figures of panel i from the stacked sum (its veil from the buffer's slot). */
static int panel_figures(const cv_lcd_panels *ps, const cv_lcd_accum *acc, int i,
                         const cv_lcd_read_params *rp, cv_lcd_accum **crop, cv_lcd_readability *rd,
                         cv_err *err) {
  int st = cv_lcd_layout_crop(&ps->L, acc, i, crop);
  if (st) return cv_err_set(err, st, "panel %d: %s", i, cv_status_str(st));
  cv_lcd_figure lv = {0, 0};
  cv_lcd_accum_veil(*crop, 0, &lv.value, &lv.se);
  return cv_lcd_readability_compute(*crop, rp, &lv, rd, err);
}

/* The veils of every panel into one round's buffer. */
static int store_veils(cv_lcd_accum *round_buf, int n, const cv_lcd_figure *lv) {
  for (int i = 0; i < n; i++) {
    int st = cv_lcd_accum_set_veil(round_buf, i, lv[i].value, lv[i].se);
    if (st) return st;
  }
  return CV_OK;
}

/* The drive's running tallies per panel (for the closing lines). */
typedef struct drive_tally {
  int n_bad[CV_LCD_MAX_PANELS], worst_k[CV_LCD_MAX_PANELS];
  double worst[CV_LCD_MAX_PANELS];
  int absolute;
} drive_tally;

/* The figures of every panel at one step: a CSV row (the light columns
 * last) and a line per panel.  Returns 0, or the exit status with the
 * message printed. */
static int drive_row(FILE *csv, const cv_lcd_panels *ps, const cv_lcd_config *lc,
                     const cv_lcd_accum *acc, const cv_lcd_read_params *rp, double t, int k,
                     const cv_drive_state *ds, const float eye[3], const double *sun_deg,
                     const cv_lcd_illum *il, drive_tally *ty) {
  const int np = ps->L.n, multi = np > 1;
  cv_err err;
  cv_err_clear(&err);
  fprintf(csv, "%.3f,%.2f,%.4f,%.4f,%.4f", t, ds->yaw_deg, eye[0], eye[1], eye[2]);
  for (int i = 0; i < np; i++) {
    cv_lcd_readability rd;
    memset(&rd, 0, sizeof rd);
    cv_lcd_accum *crop = NULL;
    const cv_lcd_read_params q = panel_rp(rp, lc, i);
    if (panel_figures(ps, acc, i, &q, &crop, &rd, &err)) {
      cv_lcd_readability_free(&rd);
      cv_lcd_accum_destroy(crop);
      return cli_fail("lcd", 1, "drive t=%.2f s: %s: %s", t, lc->panels[i].name, err.msg);
    }
    char why[160];
    const cv_lcd_verdict_kind v = cv_lcd_verdict(&rd, &q, ty->absolute, why, sizeof why);
    ty->n_bad[i] += v == CV_LCD_UNREADABLE;
    if (rd.cr_mean.value < ty->worst[i]) ty->worst[i] = rd.cr_mean.value, ty->worst_k[i] = k;
    fprintf(csv, ",%.2f,%.6g,%.3g,%.6g,%.3g,%.6g,%.3g,%.6g,%.3g,%.6g,%.3g,%.6g,%d", sun_deg[i],
            rd.L_r.value, rd.L_r.se, rd.L_v.value, rd.L_v.se, rd.cr_mean.value, rd.cr_mean.se,
            rd.frac_ok.value, rd.frac_ok.se, rd.vl.value, rd.vl.se, rd.L_a.value,
            v == CV_LCD_UNCALIBRATED ? -1 : v == CV_LCD_READABLE);
    printf("t %6.2f s yaw %5.1f%s%s: CR %.3g +- %.2g, %.0f%% of the panel >= %g:1, L_r %.4g, "
           "L_v %.4g cd/m2, VL %.3g +- %.2g%s%s%s\n",
           t, ds->yaw_deg, multi ? " " : "", multi ? lc->panels[i].name : "", rd.cr_mean.value,
           rd.cr_mean.se, 100 * rd.frac_ok.value, q.cr_min, rd.L_r.value, rd.L_v.value,
           rd.vl.value, rd.vl.se, v == CV_LCD_UNCALIBRATED ? "  [uncalibrated]" : "",
           v == CV_LCD_UNREADABLE ? "  UNREADABLE: " : "", v == CV_LCD_UNREADABLE ? why : "");
    cv_lcd_readability_free(&rd);
    cv_lcd_accum_destroy(crop);
  }
  fprintf(csv, ",%d,%.6g,%.6g,%.6g\n", ty->absolute, il->outdoor_h, il->eye_h, il->eye_v);
  return 0;
}

/* One step of the drive: its lighting, eye, rounds, veils and light level,
 * then drive_row.  Returns 0, or the exit status with the message printed. */
static int drive_step(FILE *csv, const cv_drive *d, const cv_head_path *hp, const drive_job *j,
                      const cv_prt *p, const cv_tracer *tr, const cv_lcd_panels *ps,
                      const cv_lcd_config *lc, const cv_lcd_params *par0,
                      const cv_lcd_read_params *rp, const cv_lcd_veil_params *vp, int k,
                      drive_tally *ty) {
  const double t = k * j->dt;
  cv_err err;
  cv_err_clear(&err);
  cv_drive_state ds;
  cv_drive_eval(d, t, &ds);
  cv_light_spec spec;
  cv_drive_to_light_spec(d, &ds, &spec);
  cv_scene_light *sl = NULL;
  cv_lcd_light *light = NULL;
  cv_lcd_accum *round_buf = NULL;
  cv_lcd_progress prog;
  memset(&prog, 0, sizeof prog);
  float eye[3];
  if (hp) {
    cv_head_pose hpose;
    cv_head_path_eval(hp, t, 1, &hpose);
    for (int a = 0; a < 3; a++) eye[a] = (float)(hpose.pos[a] + j->offset[a]);
  } else {
    for (int a = 0; a < 3; a++) eye[a] = (float)j->eye[a];
  }
  cv_lcd_params par = *par0;
  cv_lcd_key key;
  cv_lcd_figure lv[CV_LCD_MAX_PANELS];
  double sun_deg[CV_LCD_MAX_PANELS];
  int rc = 0;
  if (cv_scene_light_build(&spec, (int)p->bands, &sl, &err) ||
      cv_lcd_light_from_scene(sl, &spec, p, tr, lc->sun_samples, lc->env_width, &light, &err)) {
    rc = cli_fail("lcd", 1, "drive t=%.2f s: %s", t, err.msg);
  } else {
    const double clamp = cv_lcd_panels_clamp(ps, light, lc->clamp);
    const uint64_t setup = cv_lcd_panels_setup_hash(ps, &par, clamp, lc->eye_tolerance, p->meta.input_hash);
    if (cv_lcd_key_make(eye, lc->eye_tolerance, light->hash, setup, &key)) {
      rc = cli_fail("lcd", 1, "drive t=%.2f s: eye %g,%g,%g out of range", t, eye[0], eye[1], eye[2]);
    } else {
      cv_lcd_key_eye(&key, lc->eye_tolerance, par.eye);
      int st = cv_lcd_panels_veils(ps, light, par.eye, vp, lv, sun_deg);
      if (!st) st = cv_lcd_accum_create(ps->L.W, ps->L.H, clamp, &round_buf);
      for (int r = 0; r < lc->rounds && !st; r++) {
        cv_lcd_accum_clear(round_buf);
        st = cv_lcd_panels_round(ps, light, &par, (uint32_t)r, round_buf);
        if (!st) st = store_veils(round_buf, ps->L.n, lv);
        if (!st) st = cv_lcd_progress_submit(&prog, &key, round_buf, NULL);
      }
      if (st) rc = cli_fail("lcd", 1, "drive t=%.2f s: %s", t, cv_status_str(st));
    }
  }
  if (!rc) {
    cv_lcd_illum il;
    cv_lcd_illuminance(ps->g[0], light, par.eye, &il);
    rc = drive_row(csv, ps, lc, prog.acc, rp, t, k, &ds, par.eye, sun_deg, &il, ty);
  }
  fflush(stdout);
  cv_lcd_progress_free(&prog);
  cv_lcd_accum_destroy(round_buf);
  cv_lcd_light_destroy(light);
  cv_scene_light_destroy(sl);
  return rc;
}

static int lcd_drive(const drive_job *j, const cv_prt *p, const cv_tracer *tr,
                     const cv_lcd_panels *ps, const cv_lcd_config *lc, const cv_lcd_params *par0,
                     const cv_lcd_read_params *rp, const cv_lcd_veil_params *vp) {
  cv_err err;
  cv_err_clear(&err);
  cv_drive *d = NULL;
  cv_head_path *hp = NULL;
  const int np = ps->L.n, multi = np > 1;
  if (cv_drive_load(j->drive_path, &d, &err)) return cli_fail("lcd", 1, "--drive: %s", err.msg);
  if (j->head_path && cv_head_path_load(j->head_path, &hp, &err)) {
    cv_drive_destroy(d);
    return cli_fail("lcd", 1, "--head-path: %s", err.msg);
  }
  const double dur = cv_drive_duration(d);
  const int n = (int)floor(dur / j->dt + 1e-9) + (cv_drive_loops(d) ? 0 : 1);
  cv_outfile o;
  if (cv_outfile_open(&o, j->csv, 1, &err)) {
    cv_drive_destroy(d);
    cv_head_path_destroy(hp);
    return cli_fail("lcd", 1, "%s", err.msg);
  }
  /* one panel: the plain column names; several: each panel's 13 columns
   * prefixed with its name; the light level's columns last */
  static const char *const cols[13] = {"sun_glare_deg", "L_r", "L_r_se", "L_v", "L_v_se", "CR",
                                       "CR_se", "area_meeting", "area_meeting_se", "VL", "VL_se",
                                       "L_a", "readable"};
  fprintf(o.f, "t_s,yaw_deg,eye_x,eye_y,eye_z");
  for (int i = 0; i < np; i++)
    for (int c = 0; c < 13; c++)
      fprintf(o.f, ",%s%s%s", multi ? lc->panels[i].name : "", multi ? "." : "", cols[c]);
  fprintf(o.f, ",light_absolute,E_outdoor_h,E_eye_h,E_eye_v\n");
  /* the calibration is the drive's (every step's spec has the same) */
  drive_tally ty;
  memset(&ty, 0, sizeof ty);
  for (int i = 0; i < np; i++) ty.worst[i] = INFINITY;
  {
    cv_drive_state ds0;
    cv_light_spec spec0;
    char origin[CV_PATH_MAX + 16];
    cv_lcd_calib cal;
    cv_drive_eval(d, 0, &ds0);
    cv_drive_to_light_spec(d, &ds0, &spec0);
    snprintf(origin, sizeof origin, "drive %s", j->drive_path);
    cv_lcd_calibration(&spec0, origin, &cal);
    ty.absolute = cal.absolute;
    printf("light: %s: %s\n", cal.absolute ? (cal.assumed ? "absolute by ASSUMPTION" : "absolute")
                                           : "UNCALIBRATED (no verdict)", cal.source);
  }
  printf("drive: %s, %.1f s, %d steps of %.2f s; eye from %s\n", j->drive_path, dur, n < 1 ? 1 : n,
         j->dt, j->head_path ? j->head_path : "--eye");
  int rc = 0;
  for (int k = 0; k < (n < 1 ? 1 : n) && !rc; k++)
    rc = drive_step(o.f, d, hp, j, p, tr, ps, lc, par0, rp, vp, k, &ty);
  cv_drive_destroy(d);
  cv_head_path_destroy(hp);
  if (rc) {
    cv_outfile_abort(&o);
    return rc;
  }
  if (cv_outfile_commit(&o, &err)) return cli_fail("lcd", 1, "%s", err.msg);
  for (int i = 0; i < np; i++) {
    if (ty.absolute)
      printf("drive%s%s: UNREADABLE at %d of %d steps (%.1f s of %.1f s); lowest CR %.3g at t %.2f s\n",
             multi ? " " : "", multi ? lc->panels[i].name : "", ty.n_bad[i], n < 1 ? 1 : n,
             ty.n_bad[i] * j->dt, dur, ty.worst[i], ty.worst_k[i] * j->dt);
    else
      printf("drive%s%s: uncalibrated light: no verdict; lowest CR %.3g (relative units) at t %.2f s\n",
             multi ? " " : "", multi ? lc->panels[i].name : "", ty.worst[i], ty.worst_k[i] * j->dt);
  }
  char png[CV_PATH_MAX];
  snprintf(png, sizeof png, "%.*s.png", (int)(strlen(j->csv) - 4), j->csv);
  cv_err perr;
  cv_err_clear(&perr);
  const int pl = drive_plot(j->csv, png, rp->cr_min, lc, ty.absolute, &perr);
  if (pl < 0) return cli_fail("lcd", 1, "%s (%s is written)", perr.msg, j->csv);
  if (pl) printf("wrote %s and %s\n", j->csv, png);
  else printf("wrote %s (no plot: gnuplot is not installed)\n", j->csv);
  return 0;
}

/* cave lcd's command line, as given (before the configs are layered). */
typedef struct lcd_opts {
  const char *in, *out, *weights, *prt_path, *cfg_path;
  const char *brdf_s, *content_s, *sampling, *size_s;
  const char *heat_s, *drive_s, *head_s, *cave_s, *sweep_s;
  int png, have_light, have_eye, threads, spp, rounds, sweep_n;
  double sweep_lo, sweep_hi, area_min, vl_min;
  char light_origin[CV_PATH_MAX + 32]; /* where the lighting came from (light_level.h) */
  double lum, eye[3], black, cr_min, age, pigment;
  double dt, offset[3];
  cv_lcd_read_params rp;
  cv_lcd_veil_params vp;
  long long seed;
  cv_light_spec spec;
} lcd_opts;

/* --seed: an integer 0..4294967295 (lcd.seed's range), digits only. */
static int parse_seed(const char *s, long long *out) {
  if (!s || !*s || strlen(s) > 10) return -1;
  long long v = 0;
  for (const char *c = s; *c; c++) {
    if (*c < '0' || *c > '9') return -1;
    v = 10 * v + (*c - '0');
  }
  if (v > 4294967295LL) return -1;
  *out = v;
  return 0;
}

/* Reads argv into o.  Returns -1 to go on, else the exit status (0 after
 * --help; 2 with the message printed for a bad option). */
static int parse_opts(int argc, char **argv, lcd_opts *o) {
  memset(o, 0, sizeof *o);
  o->spp = o->rounds = -1;
  o->lum = o->black = o->cr_min = o->age = o->pigment = o->area_min = o->vl_min = -1;
  snprintf(o->light_origin, sizeof o->light_origin, "command line");
  o->dt = 0.5;
  o->offset[0] = -0.37, o->offset[1] = -0.18, o->offset[2] = 0; /* configs/caves/cave5.json's scene_offset */
  cv_lcd_read_params_default(&o->rp);
  cv_lcd_veil_params_default(&o->vp);
  o->seed = -1;
  cv_light_spec_default(&o->spec);
  static const char *const value_opts[] = {
      "-o", "--adaptation", "--age", "--area-min", "--black", "--brdf", "--cave", "--content",
      "--cr-min", "--drive", "--dt", "--eye", "--glare-spc", "--head-path", "--heatmap",
      "--illuminance-sweep", "--lcd-config", "--luminance", "--pigment", "--prt", "--rounds",
      "--sampling", "--scene-offset", "--seed", "--size", "--spp", "--threads", "--vl-min", NULL};
  for (int i = 1, st; i < argc; i++) {
    const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (!strcmp(a, "--png")) {
      o->png = 1;
    } else if (!strcmp(a, "--no-sun")) {
      o->spec.extract_sun = 0;
    } else if (a[0] == '-' && !val) {
      return cli_value_missing("lcd", help, a, value_opts);
    } else if ((st = cli_parse_light("lcd", argc, argv, &i, &o->spec, &o->weights)) != 0) {
      if (st < 0) return -st;
      /* the car's orientation alone is no lighting source */
      if (strcmp(a, "--yaw") && strcmp(a, "--pitch") && strcmp(a, "--roll")) o->have_light = 1;
    } else if (!strcmp(a, "-o")) {
      o->out = argv[++i];
    } else if (!strcmp(a, "--eye")) {
      if (cli_parse_vec(argv[++i], 3, o->eye)) return cli_fail("lcd", 2, "--eye: expected x,y,z, got '%s'", val);
      o->have_eye = 1;
    } else if (!strcmp(a, "--spp")) {
      if (cli_parse_int(argv[++i], 1, 65536, &o->spp)) return cli_fail("lcd", 2, "--spp: expected 1..65536, got '%s'", val);
    } else if (!strcmp(a, "--rounds")) {
      if (cli_parse_int(argv[++i], 1, 100000, &o->rounds)) return cli_fail("lcd", 2, "--rounds: expected 1..100000, got '%s'", val);
    } else if (!strcmp(a, "--size")) {
      o->size_s = argv[++i];
    } else if (!strcmp(a, "--brdf")) {
      o->brdf_s = argv[++i];
    } else if (!strcmp(a, "--sampling")) {
      o->sampling = argv[++i];
      if (strcmp(o->sampling, "brdf") && strcmp(o->sampling, "cosine") && strcmp(o->sampling, "mis"))
        return cli_fail("lcd", 2, "--sampling: expected brdf, cosine or mis, got '%s'", o->sampling);
    } else if (!strcmp(a, "--content")) {
      o->content_s = argv[++i];
    } else if (!strcmp(a, "--luminance")) {
      if (cli_parse_double(argv[++i], &o->lum) || !(o->lum >= 0 && o->lum <= CV_LCD_LUMINANCE_MAX)) return cli_fail("lcd", 2, "--luminance: expected cd/m^2 in 0..1e6, got '%s'", val);
    } else if (!strcmp(a, "--black")) {
      if (cli_parse_double(argv[++i], &o->black) || !(o->black >= 0 && o->black <= CV_LCD_LUMINANCE_MAX)) return cli_fail("lcd", 2, "--black: expected cd/m^2 in 0..1e6, got '%s'", val);
    } else if (!strcmp(a, "--cr-min")) {
      if (cli_parse_double(argv[++i], &o->cr_min) || !(o->cr_min >= 1 && o->cr_min <= CV_LCD_CR_MAX)) return cli_fail("lcd", 2, "--cr-min: expected a ratio in 1..1000, got '%s'", val);
    } else if (!strcmp(a, "--age")) {
      if (cli_parse_double(argv[++i], &o->age) || !(o->age >= 0) || o->age > 150) return cli_fail("lcd", 2, "--age: expected years in 0..150, got '%s'", val);
    } else if (!strcmp(a, "--pigment")) {
      if (cli_parse_double(argv[++i], &o->pigment) || !(o->pigment >= 0 && o->pigment <= 1)) return cli_fail("lcd", 2, "--pigment: expected 0..1, got '%s'", val);
    } else if (!strcmp(a, "--adaptation")) {
      if (cli_parse_double(argv[++i], &o->rp.adaptation) || !(o->rp.adaptation >= 0 && o->rp.adaptation <= CV_LCD_LUMINANCE_MAX)) return cli_fail("lcd", 2, "--adaptation: expected cd/m^2 in 0..1e6 (0 = automatic), got '%s'", val);
    } else if (!strcmp(a, "--area-min")) {
      if (cli_parse_double(argv[++i], &o->area_min) || !(o->area_min >= 0 && o->area_min <= 1)) return cli_fail("lcd", 2, "--area-min: expected a share of the panel area in 0..1, got '%s'", val);
    } else if (!strcmp(a, "--vl-min")) {
      if (cli_parse_double(argv[++i], &o->vl_min) || !(o->vl_min >= 0 && o->vl_min <= 1e6)) return cli_fail("lcd", 2, "--vl-min: expected a visibility level in 0..1e6, got '%s'", val);
    } else if (!strcmp(a, "--illuminance-sweep")) {
      char why[200];
      o->sweep_s = argv[++i];
      if (cv_lcd_sweep_parse(o->sweep_s, &o->sweep_lo, &o->sweep_hi, &o->sweep_n, why, sizeof why))
        return cli_fail("lcd", 2, "--illuminance-sweep: %s", why);
    } else if (!strcmp(a, "--drive")) {
      o->drive_s = argv[++i];
    } else if (!strcmp(a, "--head-path")) {
      o->head_s = argv[++i];
    } else if (!strcmp(a, "--cave")) {
      o->cave_s = argv[++i];
    } else if (!strcmp(a, "--scene-offset")) {
      if (cli_parse_vec(argv[++i], 3, o->offset) || fabs(o->offset[0]) > 1e4 || fabs(o->offset[1]) > 1e4 || fabs(o->offset[2]) > 1e4)
        return cli_fail("lcd", 2, "--scene-offset: expected x,y,z in metres (each within +-1e4), got '%s'", val);
    } else if (!strcmp(a, "--dt")) {
      if (cv_parse_seconds(argv[++i], &o->dt) || !(o->dt >= 0.01 && o->dt <= 3600)) return cli_fail("lcd", 2, "--dt: expected 0.01..3600 s (0.5 or 1/2), got '%s'", val);
    } else if (!strcmp(a, "--glare-spc")) {
      if (cli_parse_int(argv[++i], 2, 4096, &o->vp.spc) || o->vp.spc % 2) return cli_fail("lcd", 2, "--glare-spc: expected an even number 2..4096, got '%s'", val);
    } else if (!strcmp(a, "--heatmap")) {
      o->heat_s = argv[++i];
    } else if (!strcmp(a, "--lcd-config")) {
      o->cfg_path = argv[++i];
    } else if (!strcmp(a, "--prt")) {
      o->prt_path = argv[++i];
    } else if (!strcmp(a, "--seed")) {
      if (parse_seed(argv[++i], &o->seed)) return cli_fail("lcd", 2, "--seed: expected 0..4294967295 (as lcd.seed), got '%s'", val);
    } else if (!strcmp(a, "--threads")) {
      if (cli_parse_int(argv[++i], 1, 1024, &o->threads)) return cli_fail("lcd", 2, "--threads: expected 1..1024, got '%s'", val);
    } else if (a[0] == '-') {
      cli_print_usage(help);
      return cli_fail("lcd", 2, "unknown option '%s'", a);
    } else {
      if (o->in) return cli_fail("lcd", 2, "more than one input ('%s' and '%s')", o->in, a);
      o->in = a;
    }
  }
  return -1;
}

/* Loads every panel's BRDF once and prints what it is (grid, albedo,
 * MERL gaps, albedo above 1), so that a bad file fails before any long
 * work.  Returns 0, or the exit status with the message printed. */
static int check_brdfs(const cv_lcd_config *lc) {
  const int multi = lc->n_panels > 1;
  cv_err err;
  cv_err_clear(&err);
  for (int i = 0; i < lc->n_panels; i++) {
    cv_brdf_report brep;
    cv_brdf *brdf = NULL;
    if (cv_brdf_load(lc->panels[i].brdf, &brdf, &brep, &err))
      return cli_fail("lcd", 1, "%s%s%s", multi ? lc->panels[i].name : "", multi ? ": " : "", err.msg);
    printf("brdf%s%s: %s, %dx%dx%d grid; directional albedo max %.4f at %.0f deg",
           multi ? " " : "", multi ? lc->panels[i].name : "", brdf->source, brdf->n_theta,
           brdf->n_theta, brdf->n_phi, brep.albedo_max, brep.albedo_max_deg);
    if (brep.merl_missing)
      printf("; MERL: %llu missing samples read as 0 (%llu grid points on them)",
             (unsigned long long)brep.merl_missing, (unsigned long long)brep.merl_missing_used);
    printf("\n");
    if (brep.albedo_violations)
      printf("warning: brdf: directional albedo above 1 at %d view angles (from %.0f deg): the "
             "table reflects more light than it receives\n",
             brep.albedo_violations, brep.first_violation_deg);
    cv_brdf_destroy(brdf);
  }
  return 0;
}

/* --eye against the scene, before any rendering: inside the mesh's bounding
 * box grown by CV_LCD_EYE_MARGIN, and in front of every panel (a panel is
 * flat: an eye behind its plane sees its back from every texel, and the
 * figures would be those of a black panel).  Only this offline command
 * refuses such an eye; the service (`cave run`) renders whatever head it is
 * given.  Returns 0, or 2 with the message printed. */
#define CV_LCD_EYE_MARGIN 0.05
static int check_eye(const double eye[3], const cv_lcd_layout *L, const cv_lcd_config *lc,
                     const cv_mesh *m) {
  float lo[3], hi[3];
  cv_mesh_bounds(m, lo, hi);
  for (int k = 0; k < 3; k++)
    if (!(eye[k] >= lo[k] - CV_LCD_EYE_MARGIN && eye[k] <= hi[k] + CV_LCD_EYE_MARGIN))
      return cli_fail("lcd", 2,
                      "--eye: %g,%g,%g is outside the scene (bounding box %.3f..%.3f, %.3f..%.3f, "
                      "%.3f..%.3f m, grown by %g m): expected the driver's eye inside the car",
                      eye[0], eye[1], eye[2], lo[0], hi[0], lo[1], hi[1], lo[2], hi[2],
                      CV_LCD_EYE_MARGIN);
  for (int i = 0; i < L->n; i++) {
    const cv_lcd_panel *pn = &L->rect[i];
    double d = 0;
    for (int k = 0; k < 3; k++) d += (eye[k] - pn->center[k]) * pn->normal[k];
    if (!(d > 1e-6))
      return cli_fail("lcd", 2,
                      "--eye: %g,%g,%g is behind panel '%s' (%.3f m behind its plane, normal "
                      "%.3f,%.3f,%.3f): it would see the panel's back; expected an eye in front of it",
                      eye[0], eye[1], eye[2], lc->panels[i].name, -d, pn->normal[0], pn->normal[1],
                      pn->normal[2]);
  }
  return 0;
}

/* Prints a panel's figures: samples, the reflection's error, where the
 * rays went, the reflection and veil, CR and VL. */
static void print_panel(const char *nm, const cv_lcd_accum *acc, const cv_lcd_error *e,
                        const cv_lcd_read_params *q, const cv_lcd_readability *rd,
                        const cv_lcd_veil_params *vp, double sun_deg, const lcd_light_info *li) {
  const int64_t *d = acc->data;
  int64_t rays = d[CV_LCD_ACC_HITS] + d[CV_LCD_ACC_ENV] + d[CV_LCD_ACC_LOST];
  printf("lcd %s: %lld samples per texel; estimated relative RMS error of the reflection %.2f%%; "
         "rays: %.1f%% interior, %.1f%% environment, %.2f%% lost; sun reached %lld of %lld texel "
         "rounds; clamped %lld, non-finite %lld, behind the panel %lld\n",
         nm, (long long)d[CV_LCD_ACC_SPP], 100 * e->rel_rms,
         rays ? 100.0 * d[CV_LCD_ACC_HITS] / rays : 0.0, rays ? 100.0 * d[CV_LCD_ACC_ENV] / rays : 0.0,
         rays ? 100.0 * d[CV_LCD_ACC_LOST] / rays : 0.0, (long long)d[CV_LCD_ACC_SUNLIT],
         (long long)d[CV_LCD_ACC_SHADOW], (long long)d[CV_LCD_ACC_CLAMPED],
         (long long)d[CV_LCD_ACC_NONFINITE], (long long)d[CV_LCD_ACC_BEHIND]);
  char sun_txt[64];
  if (sun_deg < 0) snprintf(sun_txt, sizeof sun_txt, "sun not in sight");
  else snprintf(sun_txt, sizeof sun_txt, "sun in sight at %.0f deg from the panel", sun_deg);
  printf("lcd %s: content white %.4g, black %.4g cd/m2; reflected L_r %.4g +- %.2g cd/m2; veil "
         "L_v %.4g +- %.2g cd/m2 (CIE 146, age %g, pigment %g; %s)\n",
         nm, q->white, q->black, rd->L_r.value, rd->L_r.se, rd->L_v.value, rd->L_v.se, vp->age,
         vp->pigment, sun_txt);
  const char *unc = li->cal.absolute ? "" : " [uncalibrated light]";
  printf("lcd %s: CR %.3g +- %.2g (required %g:1, ISO 15008); %.1f%% +- %.1f%% of the panel meets "
         "it (worst texel %.3g); VL %.3g +- %.2g at adaptation %.4g cd/m2 (threshold %.3g cd/m2)%s\n",
         nm, rd->cr_mean.value, rd->cr_mean.se, q->cr_min, 100 * rd->frac_ok.value,
         100 * rd->frac_ok.se, rd->cr_worst, rd->vl.value, rd->vl.se, rd->L_a.value,
         rd->dL_threshold, unc);
  char why[160];
  const cv_lcd_verdict_kind v = cv_lcd_verdict(rd, q, li->cal.absolute, why, sizeof why);
  if (v == CV_LCD_UNCALIBRATED)
    printf("lcd %s: uncalibrated: no verdict (the light's level is unknown: %s)\n", nm,
           li->cal.source);
  else
    printf("lcd %s: %s (%s; needs CR >= %g, >= %.0f%% of the area, VL >= %g)%s\n", nm,
           cv_lcd_verdict_name(v), why, q->cr_min, 100 * q->area_min, q->vl_min,
           li->cal.assumed ? " under an ASSUMED light level" : "");
}

/* The light level: where it comes from, outdoors and at the eye. */
static void print_light(const lcd_light_info *li) {
  const cv_lcd_calib *c = &li->cal;
  const char *u = c->absolute ? "lx" : "(relative units)";
  printf("light: %s: %s\n", c->absolute ? (c->assumed ? "absolute by ASSUMPTION" : "absolute")
                                        : "UNCALIBRATED", c->source);
  printf("light: horizontal illuminance outdoors %.4g %s; at the eye %.4g +- %.2g %s horizontal, "
         "%.4g +- %.2g %s vertical (facing ahead)\n",
         li->il.outdoor_h, u, li->il.eye_h, li->il.eye_h_se, u, li->il.eye_v, li->il.eye_v_se, u);
  if (!c->absolute)
    printf("light: uncalibrated: the luminances below are in the map's units and no verdict is "
           "given (absolute light: --illuminance LUX, --sky, or a config's \"illuminance\" or "
           "\"absolute\": true; docs/readability.md)\n");
}

/* Writes panel i's files: one panel: -o, -o.json, --heatmap (or
 * <stem>.cr.png); several: <stem>.<name>.exr, .exr.json, .cr.png
 * (--heatmap FILE: <FILE stem>.<name>.png); with --png the tone-mapped PNG
 * too.  Returns 0, or the exit status with the message printed. */
typedef struct panel_paths {
  char exr[CV_PATH_MAX + 40], side[CV_PATH_MAX + 48], heat[CV_PATH_MAX + 40], png[CV_PATH_MAX + 40];
} panel_paths;

/* The files of the panel named nm (see write_panel_files). */
static void make_panel_paths(const lcd_opts *o, int multi, const char *nm, panel_paths *pp) {
  const int stem = (int)strlen(o->out) - 4;
  if (multi) snprintf(pp->exr, sizeof pp->exr, "%.*s.%s.exr", stem, o->out, nm);
  else snprintf(pp->exr, sizeof pp->exr, "%s", o->out);
  snprintf(pp->side, sizeof pp->side, "%s.json", pp->exr);
  if (o->heat_s && multi) snprintf(pp->heat, sizeof pp->heat, "%.*s.%s.png", (int)strlen(o->heat_s) - 4, o->heat_s, nm);
  else if (o->heat_s) snprintf(pp->heat, sizeof pp->heat, "%s", o->heat_s);
  else snprintf(pp->heat, sizeof pp->heat, "%.*s.cr.png", (int)strlen(pp->exr) - 4, pp->exr);
  snprintf(pp->png, sizeof pp->png, "%.*s.png", (int)strlen(pp->exr) - 4, pp->exr);
}

/* An output path that is a folder cannot be written: 1 (message printed). */
static int output_is_folder(const char *opt, const char *path) {
  struct stat st;
  if (stat(path, &st) == 0 && S_ISDIR(st.st_mode))
    return cli_fail("lcd", 1, "%s: cannot write %s: it is a folder, expected a file", opt, path);
  return 0;
}

/* Every output of the run, before any work: the folders of -o and
 * --heatmap exist and are writable, and no file to write is a folder.
 * Returns 0, or the exit status with the message printed. */
static int check_outputs(const lcd_opts *o, const cv_lcd_config *lc) {
  if (cli_check_output("lcd", "-o", o->out)) return 1;
  if (o->heat_s && cli_check_output("lcd", "--heatmap", o->heat_s)) return 1;
  if (o->drive_s || o->sweep_s) {
    char png[CV_PATH_MAX + 8];
    snprintf(png, sizeof png, "%.*s.png", (int)strlen(o->out) - 4, o->out);
    return output_is_folder("-o", o->out) || output_is_folder("-o", png);
  }
  for (int i = 0; i < lc->n_panels; i++) {
    panel_paths pp;
    make_panel_paths(o, lc->n_panels > 1, lc->panels[i].name, &pp);
    if (output_is_folder("-o", pp.exr) || output_is_folder("-o", pp.side) ||
        output_is_folder(o->heat_s ? "--heatmap" : "-o", pp.heat) ||
        (o->png && output_is_folder("--png", pp.png)))
      return 1;
  }
  return 0;
}

/* The files written so far, removed when a later one fails: a failed run
 * leaves no part of its result. */
typedef struct written_files {
  char path[4 * CV_LCD_MAX_PANELS][CV_PATH_MAX + 48];
  int n;
} written_files;

static void written_add(written_files *w, const char *path) {
  if (w->n < 4 * CV_LCD_MAX_PANELS) snprintf(w->path[w->n++], sizeof w->path[0], "%s", path);
}

static int write_panel_files(const lcd_opts *o, int multi, const char *nm, const cv_lcd_layout *L,
                             int i, const cv_image *content, const cv_lcd_accum *crop,
                             const cv_lcd_error *e, const cv_lcd_key *key, double render_s,
                             const char *brdf_source, const cv_lcd_readability *rd,
                             const cv_lcd_read_params *q, const lcd_light_info *li,
                             written_files *wf) {
  panel_paths pp;
  make_panel_paths(o, multi, nm, &pp);
  const char *exrp = pp.exr, *side = pp.side, *heatp = pp.heat;
  cv_err err;
  cv_err_clear(&err);
  cv_image *pc = NULL, *img = NULL;
  if (cv_image_create(L->w[i], L->h[i], 3, &pc)) return cli_fail("lcd", 1, "out of memory");
  for (int y = 0; y < L->h[i]; y++)
    memcpy(cv_image_at(pc, 0, y), cv_image_at(content, 0, L->y0[i] + y), 3 * (size_t)L->w[i] * sizeof(float));
  int rc = 0;
  if (cv_lcd_accum_to_image(crop, pc, &img) || cv_exr_write(exrp, img, 0, CV_EXR_ZIP, &err) ||
      (written_add(wf, exrp), 0) ||
      write_sidecar(side, crop, e, key, render_s, brdf_source, rd, q, &o->vp, li, &err) ||
      (written_add(wf, side), 0) || write_heatmap(heatp, rd, nm, q, li, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg[0] ? err.msg : "cannot make the image");
  } else if (written_add(wf, heatp), o->png) {
    cv_preview_stats pst;
    if (cv_preview_write_png(pp.png, img, 0, &pst, &err)) rc = cli_fail("lcd", 1, "%s", err.msg);
    else printf("wrote %s (exposure %.4g)\n", pp.png, pst.exposure), written_add(wf, pp.png);
  }
  if (!rc) printf("wrote %s, %s and %s\n", exrp, side, heatp);
  cv_image_destroy(img);
  cv_image_destroy(pc);
  return rc;
}

/* Every panel's readability figures, then (all of them computed and
 * printed) its files.  Returns the exit status. */
static int report_panels(const lcd_opts *o, const cv_lcd_config *lc, const cv_lcd_layout *L,
                         const cv_lcd_panels *ps, const cv_lcd_accum *all, const cv_image *content,
                         const cv_lcd_key *key, double render_s, const double *sun_deg,
                         const lcd_light_info *li) {
  const int multi = lc->n_panels > 1;
  int rc = 0;
  cv_err err;
  cv_err_clear(&err);
  cv_lcd_accum *crop[CV_LCD_MAX_PANELS] = {NULL};
  cv_lcd_readability rd[CV_LCD_MAX_PANELS];
  cv_lcd_read_params q[CV_LCD_MAX_PANELS];
  cv_lcd_error e[CV_LCD_MAX_PANELS];
  memset(rd, 0, sizeof rd);
  for (int i = 0; i < L->n && !rc; i++) {
    q[i] = panel_rp(&o->rp, lc, i);
    if (panel_figures(ps, all, i, &q[i], &crop[i], &rd[i], &err))
      rc = cli_fail("lcd", 1, "readability of %s: %s", lc->panels[i].name, err.msg);
    else
      cv_lcd_accum_error(crop[i], &e[i]);
  }
  for (int i = 0; i < L->n && !rc; i++)
    print_panel(lc->panels[i].name, crop[i], &e[i], &q[i], &rd[i], &o->vp, sun_deg[i], li);
  written_files wf;
  wf.n = 0;
  for (int i = 0; i < L->n && !rc; i++)
    rc = write_panel_files(o, multi, lc->panels[i].name, L, i, content, crop[i], &e[i], key,
                           render_s, ps->brdf[i]->source, &rd[i], &q[i], li, &wf);
  if (rc) { /* nothing of a failed run is left behind */
    for (int k = 0; k < wf.n; k++) unlink(wf.path[k]);
  }
  for (int i = 0; i < L->n; i++) {
    cv_lcd_readability_free(&rd[i]);
    cv_lcd_accum_destroy(crop[i]);
  }
  return rc;
}

/* --- the illuminance sweep (--illuminance-sweep LO:HI[:N]) ----------------- */

/* The sweep's plot with gnuplot (when installed): CR of every panel against
 * the illuminance (log scale), the area share on the right axis, the
 * requirement, each panel's crossing and bright daylight marked.  1 when
 * written, 0 without gnuplot, -1 on failure (err set). */
static int sweep_plot(const char *csv, const char *png, const cv_lcd_config *lc,
                      const cv_lcd_read_params *rp, const double *cross, const float eye[3],
                      double lo, double hi, cv_err *err) {
  cli_plot po;
  const int b = cli_plot_begin(&po, png, err);
  if (b <= 0) return b;
  FILE *g = po.g;
  const int np = lc->n_panels, cols = 11;
  fprintf(g,
          "set terminal pngcairo size 1000,500 font ',10'\nset output '%s'\n"
          "set datafile separator ','\nset key top right box opaque\nset grid\nset logscale xy\n"
          "set xlabel 'outdoor horizontal illuminance (lx)'\nset ylabel 'contrast ratio (log scale)'\n"
          "set y2label 'share of the panel area meeting %g:1'\nset y2range [0:1.05]\n"
          "set ytics nomirror\nset y2tics 0.2\nset yrange [1:*]\nset xrange [%g:%g]\n"
          "set format x '%%.0f'\n"
          "set title 'LCD readability against the light level (eye %.3f %.3f %.3f m, the sun as "
          "given): CR falls to %g:1 at",
          po.of.tmp, rp->cr_min, lo, hi, eye[0], eye[1], eye[2], rp->cr_min);
  for (int i = 0; i < np; i++)
    fprintf(g, "%s %s %.0f lx", i ? "," : "", lc->panels[i].name, cross[i]);
  fprintf(g, "'\n");
  if (lo <= 1e5 && hi >= 1e5) /* bright daylight, for comparison */
    fprintf(g, "set arrow from 100000, graph 0 to 100000, graph 1 nohead dt 3 lw 2 lc rgb '#888888'\n"
               "set label 'bright daylight, about 100000 lx' at 100000, graph 0.5 right offset -0.5,0 "
               "tc rgb '#555555'\n");
  static const char *const col[CV_LCD_MAX_PANELS] = {"#3b528b", "#21918c", "#5ec962", "#440154"};
  for (int i = 0; i < np; i++)
    if (cross[i] > 0)
      fprintf(g, "set arrow from %g, graph 0 to %g, graph 1 nohead dt 2 lc rgb '%s'\n", cross[i],
              cross[i], col[i % CV_LCD_MAX_PANELS]);
  fprintf(g, "plot ");
  for (int i = 0; i < np; i++) {
    const int c = 2 + cols * i + 4; /* the panel's CR column (1-based) */
    fprintf(g,
            "'%s' using 1:%d with linespoints lc rgb '%s' pt 7 ps 0.6 title 'CR %s', "
            "'' using 1:%d axes x1y2 with lines dt 4 lc rgb '%s' title 'area share %s', ",
            csv, c, col[i], lc->panels[i].name, c + 2, col[i], lc->panels[i].name);
  }
  fprintf(g, "%g with lines dt 2 lw 2 lc rgb '#d62728' title 'required %g:1'\n", rp->cr_min,
          rp->cr_min);
  return cli_plot_end(&po, png, err);
}

/* One panel's sweep summary from the grid's columns and the closed form. */
static void sweep_report(const char *nm, const cv_lcd_readability *ref, const cv_lcd_read_params *q,
                         double E_ref, const double *E, const double *area, const double *vl,
                         const int *ok, int n, double *cross) {
  double Es, se, Ea, Ev;
  const int has = cv_lcd_sweep_crossing(ref, q, E_ref, &Es, &se);
  *cross = has ? Es : 0;
  if (has)
    printf("sweep %s: the mean CR falls to %g:1 at %.4g +- %.2g lx%s\n", nm, q->cr_min, Es, se,
           Es < E[0] || Es > E[n - 1] ? " (outside the sweep)" : "");
  else
    printf("sweep %s: the mean CR %s %g:1 at every light level\n", nm,
           q->white > q->cr_min * q->black ? "meets" : "never meets", q->cr_min);
  if (cv_lcd_sweep_grid_crossing(E, area, q->area_min, n, &Ea))
    printf("sweep %s: the area meeting %g:1 falls below %.0f%% at about %.4g lx (between sweep steps)\n",
           nm, q->cr_min, 100 * q->area_min, Ea);
  else
    printf("sweep %s: the area meeting %g:1 is %s %.0f%% over the whole sweep\n", nm, q->cr_min,
           area[0] >= q->area_min ? "at least" : "below", 100 * q->area_min);
  if (cv_lcd_sweep_grid_crossing(E, vl, q->vl_min, n, &Ev))
    printf("sweep %s: VL falls below %g at about %.4g lx\n", nm, q->vl_min, Ev);
  int last = -1;
  while (last + 1 < n && ok[last + 1]) last++;
  if (last < 0) printf("sweep %s: UNREADABLE already at %.4g lx\n", nm, E[0]);
  else if (last == n - 1) printf("sweep %s: READABLE over the whole sweep, up to %.4g lx\n", nm, E[n - 1]);
  else printf("sweep %s: READABLE up to %.4g lx, UNREADABLE from %.4g lx (sweep steps)\n", nm,
              E[last], E[last + 1]);
}

/* The figures of every panel at each level of the sweep from the one
 * render `all` (sweep.h), the CSV, the crossings and the plot. */
static int lcd_sweep(const lcd_opts *o, const cv_lcd_config *lc, const cv_lcd_panels *ps,
                     const cv_lcd_accum *all, const lcd_light_info *li, const float eye[3]) {
  const double E_ref = li->il.outdoor_h;
  if (!(E_ref > 0))
    return cli_fail("lcd", 1, "--illuminance-sweep: the lighting has no horizontal illuminance "
                    "(a black upper hemisphere): there is no level to scale");
  const int np = ps->L.n, n = o->sweep_n, multi = np > 1;
  printf("sweep: %d levels %g..%g lx from one render at the lighting's own level (outdoor "
         "horizontal illuminance %.4g %s), reflection and veil scaled (both are linear in the light)\n",
         n, o->sweep_lo, o->sweep_hi, E_ref, li->cal.absolute ? "lx" : "in the map's units");
  cv_err err;
  cv_err_clear(&err);
  cv_lcd_accum *crop[CV_LCD_MAX_PANELS] = {NULL};
  cv_lcd_readability ref[CV_LCD_MAX_PANELS];
  cv_lcd_read_params q[CV_LCD_MAX_PANELS];
  memset(ref, 0, sizeof ref);
  double *E = calloc((size_t)n, sizeof *E), *buf = calloc((size_t)n * 2 * np, sizeof *buf);
  int *ok = calloc((size_t)n * np, sizeof *ok), rc = 0;
  cv_outfile f;
  if (!E || !buf || !ok) rc = cli_fail("lcd", 1, "out of memory");
  else if (cv_outfile_open(&f, o->out, 1, &err)) rc = cli_fail("lcd", 1, "%s", err.msg);
  for (int i = 0; i < np && !rc; i++) {
    q[i] = panel_rp(&o->rp, lc, i);
    if (panel_figures(ps, all, i, &q[i], &crop[i], &ref[i], &err))
      rc = cli_fail("lcd", 1, "readability of %s: %s", lc->panels[i].name, err.msg);
  }
  static const char *const cols[11] = {"L_r", "L_r_se", "L_v", "L_v_se", "CR", "CR_se",
                                       "area_meeting", "area_meeting_se", "VL", "VL_se", "readable"};
  if (!rc) {
    fprintf(f.f, "E_lx");
    for (int i = 0; i < np; i++)
      for (int c = 0; c < 11; c++)
        fprintf(f.f, ",%s%s%s", multi ? lc->panels[i].name : "", multi ? "." : "", cols[c]);
    fprintf(f.f, "\n");
  }
  for (int k = 0; k < n && !rc; k++) {
    E[k] = cv_lcd_sweep_level(o->sweep_lo, o->sweep_hi, n, k);
    fprintf(f.f, "%.6g", E[k]);
    for (int i = 0; i < np && !rc; i++) {
      cv_lcd_readability rd;
      const cv_lcd_figure lv = ref[i].L_v;
      if (cv_lcd_sweep_figures(crop[i], &q[i], &lv, E_ref, E[k], &rd, &err)) {
        rc = cli_fail("lcd", 1, "sweep %s at %g lx: %s", lc->panels[i].name, E[k], err.msg);
        break;
      }
      ok[i * n + k] = cv_lcd_verdict(&rd, &q[i], 1, NULL, 0) == CV_LCD_READABLE;
      buf[(2 * i) * n + k] = rd.frac_ok.value;
      buf[(2 * i + 1) * n + k] = rd.vl.value;
      fprintf(f.f, ",%.6g,%.3g,%.6g,%.3g,%.6g,%.3g,%.6g,%.3g,%.6g,%.3g,%d", rd.L_r.value, rd.L_r.se,
              rd.L_v.value, rd.L_v.se, rd.cr_mean.value, rd.cr_mean.se, rd.frac_ok.value,
              rd.frac_ok.se, rd.vl.value, rd.vl.se, ok[i * n + k]);
      cv_lcd_readability_free(&rd);
    }
    fprintf(f.f, "\n");
  }
  if (rc && E && buf && ok) cv_outfile_abort(&f);
  else if (!rc && cv_outfile_commit(&f, &err)) rc = cli_fail("lcd", 1, "%s", err.msg);
  double cross[CV_LCD_MAX_PANELS] = {0};
  for (int i = 0; i < np && !rc; i++)
    sweep_report(lc->panels[i].name, &ref[i], &q[i], E_ref, E, buf + 2 * i * n,
                 buf + (2 * i + 1) * n, ok + i * n, n, &cross[i]);
  if (!rc) {
    char png[CV_PATH_MAX];
    snprintf(png, sizeof png, "%.*s.png", (int)(strlen(o->out) - 4), o->out);
    const int pl = sweep_plot(o->out, png, lc, &o->rp, cross, eye, o->sweep_lo, o->sweep_hi, &err);
    if (pl < 0) rc = cli_fail("lcd", 1, "%s (%s is written)", err.msg, o->out);
    else if (pl) printf("wrote %s and %s\n", o->out, png);
    else printf("wrote %s (no plot: gnuplot is not installed)\n", o->out);
  }
  for (int i = 0; i < np; i++) {
    cv_lcd_readability_free(&ref[i]);
    cv_lcd_accum_destroy(crop[i]);
  }
  free(E);
  free(buf);
  free(ok);
  return rc;
}

/* The baked scene: the .prt given, or with a scene.json its --prt or a bake
 * here (the panels and the eye checked against the mesh first); a
 * scene.json's own lighting when none was given.  Returns 0 with *p, or the
 * exit status with the message printed. */
static int load_scene(lcd_opts *o, const cv_lcd_config *lc, cv_prt **p) {
  int rc = 0;
  cv_err err;
  cv_err_clear(&err);
  cv_scene_config cfg;
  cv_scene_config_default(&cfg);
  cv_mesh *m = NULL;
  cv_tracer *tr = NULL;
  if (cli_has_ext(o->in, ".json")) {
    if (cv_scene_config_load(o->in, &cfg, &err)) {
      rc = cli_fail("lcd", 1, "%s", err.msg);
      goto done;
    }
    if (!o->have_light && cfg.light.kind != CV_LIGHT_NONE) {
      double y = o->spec.yaw_deg, pi = o->spec.pitch_deg, r = o->spec.roll_deg;
      o->spec = cfg.light;
      if (y != 0) o->spec.yaw_deg = y;
      if (pi != 0) o->spec.pitch_deg = pi;
      if (r != 0) o->spec.roll_deg = r;
      o->have_light = 1;
      snprintf(o->light_origin, sizeof o->light_origin, "scene config %s", o->in);
    }
    if (o->prt_path) {
      if (cv_prt_read(o->prt_path, p, &err)) {
        rc = cli_fail("lcd", 1, "%s", err.msg);
        goto done;
      }
    } else {
      if (cv_scene_mesh_load(&cfg, stdout, &m, &err) || cv_tracer_create(m, &tr, &err)) {
        rc = cli_fail("lcd", 1, "%s", err.msg);
        goto done;
      }
      /* the panels against the scene before the bake: a panel outside it
       * fails at once */
      cv_lcd_layout L0;
      if (cv_lcd_layout_make(lc, m, &L0, &err)) {
        rc = cli_fail("lcd", 1, "%s", err.msg);
        goto done;
      }
      if (o->have_eye && !o->head_s && (rc = check_eye(o->eye, &L0, lc, m))) goto done;
      rc = 0;
      cv_bake_params bp = {.bands = cfg.bands ? cfg.bands : 5, .rays = cfg.rays ? cfg.rays : 1024,
                           .bounces = cfg.bounces, .seed = cfg.seed, .spread = (float)cfg.spread,
                           .cosine_only = !cfg.window_sampling, .tail = cfg.tail, .quiet = 1};
      printf("bake: %d bands, %d rays, %d bounces (use --prt FILE from `cave bake` to skip this)\n",
             bp.bands, bp.rays, bp.bounces);
      fflush(stdout);
      cv_tracer_set_spread(tr, bp.spread);
      cv_tracer_set_window_sampling(tr, !bp.cosine_only);
      if (cv_prt_bake_tracer(tr, &bp, p, NULL, &err)) {
        rc = cli_fail("lcd", 1, "%s", err.msg);
        goto done;
      }
      cv_tracer_destroy(tr);
      tr = NULL;
      cv_mesh_destroy(m);
      m = NULL;
    }
  } else if (cv_prt_read(o->in, p, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
done:
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
  cv_scene_config_free(&cfg);
  return rc;
}

/* A .prt's own panels: the lcd block `cave bake` wrote next to it
 * (<scene.prt>.lcd.json, lcd_config.h), or a line saying it has none.
 * Returns 0, or the exit status with the message printed. */
static int prt_lcd_block(const char *prt, cv_lcd_config *lc) {
  cv_err err;
  cv_err_clear(&err);
  uint64_t hash;
  int found;
  char from[CV_PATH_MAX];
  if (cv_prt_read_input_hash(prt, &hash, &err)) return cli_fail("lcd", 1, "%s", err.msg);
  if (cv_lcd_sidecar_load(prt, hash, lc, &found, from, sizeof from, &err))
    return cli_fail("lcd", 1, "%s", err.msg);
  if (found) printf("lcd panels: %s's lcd block (%s, baked from %s)\n", prt, lc->source, from);
  else printf("lcd panels: %s has no lcd block (bake it from a scene config with one, or give "
              "--lcd-config): one default panel on the lcd triangles\n", prt);
  return 0;
}

/* The checks of the command line and the LCD model: the defaults, the
 * scene config's (or the .prt's baked) lcd block, --lcd-config, then the
 * options; every output checked before any work.  Returns -1 to go on,
 * else the exit status with the message printed. */
static int lcd_setup(lcd_opts *o, cv_lcd_config *lc) {
  int rc0;
  cv_err err;
  cv_err_clear(&err);
  if (!o->in || !o->out || (!o->have_eye && !(o->drive_s && o->head_s))) {
    cli_print_usage(help);
    return cli_fail("lcd", 2, "an input (.prt or .json), --eye x,y,z (or --drive with --head-path) and -o FILE are required");
  }
  if (o->head_s && !o->drive_s) return cli_fail("lcd", 2, "--head-path: needs --drive");
  if (o->drive_s && !cli_has_ext(o->out, ".csv")) return cli_fail("lcd", 2, "-o: with --drive the series is written as .csv, got '%s'", o->out);
  if (o->sweep_s && o->drive_s) return cli_fail("lcd", 2, "--illuminance-sweep: not with --drive (a sweep is of one pose and sun position)");
  if (o->sweep_s && (o->png || o->heat_s)) return cli_fail("lcd", 2, "--illuminance-sweep: writes sweep.csv and its plot, not %s (run without the sweep for the panel's images)", o->png ? "--png" : "--heatmap");
  if (o->sweep_s && !cli_has_ext(o->out, ".csv")) return cli_fail("lcd", 2, "-o: with --illuminance-sweep the sweep is written as .csv, got '%s'", o->out);
  if (!o->drive_s && !o->sweep_s && !cli_has_ext(o->out, ".exr")) return cli_fail("lcd", 2, "-o: the panel is written as .exr, got '%s'", o->out);
  if (o->cave_s) {
    cv_cave cave;
    cv_err cerr;
    if (cv_cave_load(o->cave_s, &cave, &cerr)) return cli_fail("lcd", 1, "--cave: %s", cerr.msg);
    memcpy(o->offset, cave.scene_offset, sizeof o->offset);
  }
  cv_lcd_config_default(lc);
  /* the scene config's "lcd" block, then --lcd-config, then the options */
  if (cli_has_ext(o->in, ".json") && cv_lcd_config_load_scene(o->in, lc, &err))
    return cli_fail("lcd", 1, "%s", err.msg);
  if (!cli_has_ext(o->in, ".json") && (rc0 = prt_lcd_block(o->in, lc))) return rc0;
  if (o->cfg_path && cv_lcd_config_load(o->cfg_path, lc, &err)) return cli_fail("lcd", 1, "%s", err.msg);
  if (o->spp > 0) lc->spp = o->spp;
  if (o->rounds > 0) lc->rounds = o->rounds;
  if (o->size_s && cli_parse_size(o->size_s, 16384, &lc->width, &lc->height))
    return cli_fail("lcd", 2, "--size: expected WxH (1..16384), got '%s'", o->size_s);
  if (o->brdf_s) snprintf(lc->brdf, sizeof lc->brdf, "%s", o->brdf_s);
  if (o->content_s) {
    FILE *cf = fopen(o->content_s, "rb");
    if (!cf) return cli_fail("lcd", 1, "--content: %s: cannot open", o->content_s);
    fclose(cf);
    snprintf(lc->content, sizeof lc->content, "%s", o->content_s);
  }
  /* an option overrides the block and every panel's own value (docs/scene-config.md) */
  cv_lcd_config_override(lc, (o->size_s ? CV_LCD_SET_SIZE : 0u) | (o->brdf_s ? CV_LCD_SET_BRDF : 0u) |
                                  (o->content_s ? CV_LCD_SET_CONTENT : 0u) |
                                  (o->lum >= 0 ? CV_LCD_SET_WHITE : 0u) |
                                  (o->black >= 0 ? CV_LCD_SET_BLACK : 0u));
  if (o->lum >= 0) lc->content_luminance = o->lum;
  if (o->seed >= 0) lc->seed = (uint32_t)o->seed;
  if (o->sampling) lc->brdf_fraction = !strcmp(o->sampling, "brdf") ? 1.0 : !strcmp(o->sampling, "cosine") ? 0.0 : 0.9;
  if (o->threads > 0) omp_set_num_threads(o->threads);
  if (o->black >= 0) lc->black_luminance = o->black;
  if (o->cr_min >= 1) lc->cr_min = o->cr_min;
  if (o->age >= 0) lc->age = o->age;
  if (o->pigment >= 0) lc->pigment = o->pigment;
  if (cv_lcd_config_panels(lc, &err)) return cli_fail("lcd", 1, "%s", err.msg);
  o->rp.white = lc->panels[0].content_luminance;
  o->rp.black = lc->panels[0].black_luminance;
  o->rp.cr_min = lc->cr_min;
  o->vp.age = lc->age;
  o->vp.pigment = lc->pigment;
  if (o->area_min >= 0) o->rp.area_min = o->area_min;
  if (o->vl_min >= 0) o->rp.vl_min = o->vl_min;
  for (int i = 0; i < lc->n_panels; i++) {
    const cv_lcd_read_params q = panel_rp(&o->rp, lc, i);
    if (cv_lcd_read_params_check(&q, &err))
      return cli_fail("lcd", 2, "panel '%s': %s", lc->panels[i].name, err.msg);
  }
  if (o->heat_s && !cli_has_ext(o->heat_s, ".png")) return cli_fail("lcd", 2, "--heatmap: expected a .png file, got '%s'", o->heat_s);
  /* every output before any work: a bad one fails here, not after the rounds */
  const int ost = check_outputs(o, lc);
  return ost ? ost : -1;
}

int cmd_lcd(int argc, char **argv) {
  lcd_opts o;
  const int parsed = parse_opts(argc, argv, &o);
  if (parsed >= 0) return parsed;
  cv_lcd_config lc;
  const int set = lcd_setup(&o, &lc);
  if (set >= 0) return set;
  cv_err err;
  cv_err_clear(&err);
  int rc = 1;
  cv_prt *p = NULL;
  cv_mesh *m = NULL;
  cv_tracer *tr = NULL;
  cv_scene_light *sl = NULL;
  cv_lcd_light *light = NULL;
  cv_lcd_panels *ps = NULL;
  cv_lcd_accum *round_buf = NULL;
  cv_lcd_progress prog;
  memset(&prog, 0, sizeof prog);
  cv_image *content = NULL;
  int wst = cli_apply_weights("lcd", &o.spec, o.weights);
  if (wst) return wst;
  /* The BRDFs first: a bad file fails before any long work. */
  const int bst = check_brdfs(&lc);
  if (bst) return bst;
  if ((rc = load_scene(&o, &lc, &p))) goto done;
  rc = 1;
  if (!o.drive_s && (!o.have_light || o.spec.kind == CV_LIGHT_NONE)) {
    rc = cli_fail("lcd", 2, "no lighting: give --env, --env-constant or --sky");
    goto done;
  }
  double t0 = cv_now_seconds();
  if (cv_prt_to_mesh(p, &m) || cv_tracer_create(m, &tr, &err)) {
    rc = cli_fail("lcd", 1, "%s: %s", o.in, err.msg[0] ? err.msg : "out of memory");
    goto done;
  }
  cv_lcd_layout L;
  if (cv_lcd_layout_make(&lc, m, &L, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
  if (o.have_eye && !o.head_s && (rc = check_eye(o.eye, &L, &lc, m))) goto done;
  rc = 1;
  if (cv_lcd_panels_create(&lc, &L, cv_tracer_rt(tr), m, &ps, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
  /* the content before the long work: a bad file fails here */
  if (cv_lcd_layout_content(&lc, &L, &content, &err)) {
    rc = cli_fail("lcd", 1, "content: %s", err.msg);
    goto done;
  }
  cv_lcd_params par;
  cv_lcd_params_default(&par);
  par.w = L.w[0];
  par.h = L.h[0];
  par.spp = lc.spp;
  par.brdf_fraction = lc.brdf_fraction;
  /* brdf / cosine alone: no window or environment samples (mis: the default shares) */
  if (o.sampling && strcmp(o.sampling, "mis")) par.window_fraction = par.env_fraction = 0;
  par.seed = lc.seed;
  if (o.drive_s) {
    drive_job dj = {o.drive_s, o.head_s, o.out, {o.offset[0], o.offset[1], o.offset[2]},
                    {o.eye[0], o.eye[1], o.eye[2]}, o.dt};
    rc = lcd_drive(&dj, p, tr, ps, &lc, &par, &o.rp, &o.vp);
    goto done;
  }
  if (cv_scene_light_build(&o.spec, (int)p->bands, &sl, &err) ||
      cv_lcd_light_from_scene(sl, &o.spec, p, tr, lc.sun_samples, lc.env_width, &light, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
  cv_scene_light_print(stdout, sl);
  printf("lcd sun: %s; %llu vertex radiance values were not finite or negative (set to 0)\n",
         light->sun_source, (unsigned long long)light->vrad_fixed);
  for (int i = 0; i < L.n; i++) {
    const cv_lcd_panel *pn = &L.rect[i];
    printf("panel %s: %.0f x %.0f mm at %.3f %.3f %.3f, normal %.3f %.3f %.3f; %dx%d texels\n",
           lc.panels[i].name, 1000 * pn->size[0], 1000 * pn->size[1], pn->center[0], pn->center[1],
           pn->center[2], pn->normal[0], pn->normal[1], pn->normal[2], L.w[i], L.h[i]);
  }
  double clamp = cv_lcd_panels_clamp(ps, light, lc.clamp);
  const float ef[3] = {(float)o.eye[0], (float)o.eye[1], (float)o.eye[2]};
  cv_lcd_key key;
  uint64_t setup = cv_lcd_panels_setup_hash(ps, &par, clamp, lc.eye_tolerance, p->meta.input_hash);
  if (cv_lcd_key_make(ef, lc.eye_tolerance, light->hash, setup, &key)) {
    rc = cli_fail("lcd", 2, "--eye: %g,%g,%g is not representable with tolerance %g", o.eye[0],
                  o.eye[1], o.eye[2], lc.eye_tolerance);
    goto done;
  }
  cv_lcd_key_eye(&key, lc.eye_tolerance, par.eye);
  lcd_light_info li;
  cv_lcd_calibration(&o.spec, o.light_origin, &li.cal);
  cv_lcd_illuminance(ps->g[0], light, par.eye, &li.il);
  if (!o.sweep_s) print_light(&li);
  if (cv_lcd_accum_create(L.W, L.H, clamp, &round_buf)) {
    rc = cli_fail("lcd", 1, "cannot allocate a %dx%d panel buffer", L.W, L.H);
    goto done;
  }
  cv_lcd_figure lv[CV_LCD_MAX_PANELS];
  double sun_deg[CV_LCD_MAX_PANELS];
  if (cv_lcd_panels_veils(ps, light, par.eye, &o.vp, lv, sun_deg)) {
    rc = cli_fail("lcd", 1, "readability: the eye is at a panel's centre");
    goto done;
  }
  double setup_s = cv_now_seconds() - t0;
  t0 = cv_now_seconds();
  for (int r = 0; r < lc.rounds; r++) {
    cv_lcd_accum_clear(round_buf);
    int st = cv_lcd_panels_round(ps, light, &par, (uint32_t)r, round_buf);
    if (!st) st = store_veils(round_buf, L.n, lv);
    if (!st) st = cv_lcd_progress_submit(&prog, &key, round_buf, NULL);
    if (st) {
      rc = cli_fail("lcd", 1, "round %d: %s", r, cv_status_str(st));
      goto done;
    }
  }
  double render_s = cv_now_seconds() - t0;
  {
    const int64_t *d = prog.acc->data;
    int64_t rays = d[CV_LCD_ACC_HITS] + d[CV_LCD_ACC_ENV] + d[CV_LCD_ACC_LOST];
    printf("lcd: %d round(s) x %d samples per texel in %.2f s (setup %.2f s) on %d threads: %.2f M "
           "rays/s; eye %.4f %.4f %.4f\n",
           lc.rounds, par.spp, render_s, setup_s, omp_get_max_threads(),
           render_s > 0 ? rays / render_s / 1e6 : 0.0, par.eye[0], par.eye[1], par.eye[2]);
  }
  if (o.sweep_s) rc = lcd_sweep(&o, &lc, ps, prog.acc, &li, par.eye);
  else rc = report_panels(&o, &lc, &L, ps, prog.acc, content, &key, render_s, sun_deg, &li);
done:
  cv_image_destroy(content);
  cv_lcd_progress_free(&prog);
  cv_lcd_accum_destroy(round_buf);
  cv_lcd_panels_destroy(ps);
  cv_lcd_light_destroy(light);
  cv_scene_light_destroy(sl);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
  cv_prt_destroy(p);
  return rc;
}
