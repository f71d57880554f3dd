/* `cave run`: the cluster render service's entry point.  Every rank parses
 * the same command line and configuration; the checks are deterministic, so
 * all ranks agree on whether to start without exchanging a message, and
 * rank 0 alone prints the problems (every one of them).  Then each rank
 * takes its role (service.h). */
#include <arpa/inet.h>
#include <errno.h>
#include <libgen.h>
#include <stdarg.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/parse.h"
#include "comm.h"
#include "core/dirlock.h"
#include "lightshare.h"
#include "prt/prt.h"
#include "service.h"
#include "service_internal.h"
#include "service/tracker_calib.h"
#include "http/http.h"

static volatile sig_atomic_t g_stop;

static void on_signal(int sig) {
  g_stop = sig; /* the signal's number (a wall-eye names it: walleye.c watch_signal) */
}

static const char *k_builtin_drive =
    "{\"description\": \"built-in: the car stands still under blender-data's forest map\","
    " \"loop\": true, \"maps\": [\"forest.exr\"], \"scale\": 10000,"
    " \"keyframes\": [{\"t\": 0, \"yaw\": 0, \"weights\": [1]}, {\"t\": 1, \"yaw\": 0}]}";

static void help(FILE *f) {
  fprintf(f,
          "usage: mpirun -np N cave run <cave.json> --scene scene.prt [options]\n"
          "       cave run --check --ranks N <cave.json> --scene scene.prt [options]\n\n"
          "The CAVE render service: rank 0 is the master (drive, head tracker, adaptation,\n"
          "LCD sums, scattering compensation, metrics), ranks 1..2W render the W walls'\n"
          "left and right eyes, further ranks only path-trace the dashboard LCD.\n\n"
          "options:\n"
          "  --scene FILE.prt     baked scene (cave bake); required\n"
          "  --drive FILE.json    scripted drive (configs/drives/); default: the car stands\n"
          "                       still under blender-data's forest map\n"
          "  --head-path FILE     recorded head path (t x y z gx gy gz per line)\n"
          "  --dtrack PORT        live ART DTrack ASCII head tracking on this UDP port\n"
          "  --dtrack-host ADDR   bind address (default 127.0.0.1)\n"
          "  --dtrack-body ID     the head's body id (default 1)\n"
          "  --tracker FILE       calibrated DTrack head tracking as the tracker config says\n"
          "                       (units, room-to-CAVE transform, body, eye offset, IPD, roll,\n"
          "                       unicast or multicast: docs/tracker.md); not with --dtrack\n"
          "  --frames N           frames to render (default 30; 0 = until SIGINT/SIGTERM)\n"
          "  --dt S               simulated seconds per frame, 0.0333 or 1/30 (default 1/30)\n"
          "  --size N             every wall at N pixels on its longer side, aspect kept, as in\n"
          "                       cave render (default: the config's res)\n"
          "  --max-fps F          pace the frames to at most F per second (default: free;\n"
          "                       the idle LCD threads use what the renderers leave)\n"
          "  --write-every K      write images every K-th frame (default 10; 0: last only)\n"
          "  --timeout-ms T       wait at most T ms for late ranks per frame (default 2000)\n"
          "  --gather-timeout S   a gather rank silent S s is dead: named, its LCD rounds go to\n"
          "                       the others; a wall-eye silent S s stops the run; a rank\n"
          "                       declared dead leaves if it runs again (default 10; 0.5..3600)\n"
          "  --present WHAT       files, window, desktop, none, or a list: window,files or\n"
          "                       desktop,files (default files).\n"
          "                       window: one borderless window per output of the CAVE config\n"
          "                       (its host, X display, geometry or fullscreen), vsync, swap\n"
          "                       lock; Escape or closing a window stops the service.\n"
          "                       desktop: no CAVE needed: one window on the master's $DISPLAY\n"
          "                       shows the unfolded CAVE; arrows/WASD, PageUp/PageDown (Q/E),\n"
          "                       left-drag and R steer the head (docs/desktop.md); not with\n"
          "                       window\n"
          "  --desktop-view V     cross (default: every wall, unfolded) or a wall's name\n"
          "  --desktop-fps F      at most F preview images a second (default 30; 0: every\n"
          "                       frame)\n"
          "  --gpu G              auto, software or a hardware EGL device index N, for every\n"
          "                       output (default: each output's \"gpu\"); auto prefers hardware,\n"
          "                       and a hardware request never falls back to llvmpipe\n"
          "  --transfer T         how each wall-eye stores the transfer vectors: auto (default:\n"
          "                       half floats when it relights on the CPU, i.e. llvmpipe;\n"
          "                       floats on a GPU), float or half (as `cave render`)\n"
          "  --clock C            wall (real time: paced to the config's rate, drive and sun\n"
          "                       follow the clock) or sim (fixed --dt per frame, reproducible);\n"
          "                       default wall with window or desktop, else sim\n"
          "  --no-predict         use the newest head pose as it is (default: predicted to\n"
          "                       the expected scan-out, constant velocity; wall clock only)\n"
          "  --predict-horizon S  predict at most S seconds ahead (default 0.1)\n"
          "  --barrier            swap lock also without windows\n"
          "  --swap-sync S        scheduled (default: the master sends every rank one swap\n"
          "                       time once all are ready; each sleeps to it) or barrier\n"
          "                       (MPI_Ibarrier among the render ranks, swap on release)\n"
          "  --swap-margin-ms T   scheduled swaps: the swap time is T ms after the last rank\n"
          "                       is ready (default 3)\n"
          "  --share-lighting S   auto (default): background on a hardware GL, host on a\n"
          "                       software GL with fewer than 4 cores per wall-eye on the\n"
          "                       host, else off (the ready line says what it picked).\n"
          "                       host: the wall-eyes of one host with the same\n"
          "                       scene and GL compute each lighting change once: the first\n"
          "                       (leader) relights, draws the sun's shadow map and the\n"
          "                       background into shared memory, the others upload them\n"
          "                       (the same images, byte for byte); an importer waits for\n"
          "                       the leader at most --timeout-ms / 4, then computes itself\n"
          "                       (counted: docs/metrics.md).  The leader also computes the\n"
          "                       next frame's lighting ahead, predicted from the drive, and\n"
          "                       publishes it when the next state confirms it bit for bit.\n"
          "                       host-now: sharing without that prefetch; background:\n"
          "                       only the background image is shared, each wall-eye\n"
          "                       relights and draws its shadow map on its own GL; off:\n"
          "                       every wall-eye computes its own\n"
          "  --display FILE.json  compensation display, or a CAVE config whose walls and\n"
          "                       \"screens\" give it (default: generated from the walls)\n"
          "  --patches P          patches per wall side of the generated display (default: the\n"
          "                       config's screens.patches, 24)\n"
          "  --reflectance R      screen reflectance of the generated display, 0 <= R < 1 as\n"
          "                       screens.reflectance (1 would reflect all light for ever)\n"
          "                       (default: the config's screens.reflectance, 0.8)\n"
          "  --compensation-ms T  time slot of the compensation solve per frame (default 20;\n"
          "                       warm-started from the previous frame)\n"
          "  --compensation-lag L 1 (default): frame N shows the correction solved from frame\n"
          "                       N-1's patch means, by the master's solver thread while N\n"
          "                       renders (off the frame's path); 0: frame N's own, each\n"
          "                       wall-eye waiting for the master's solve (docs/service.md)\n"
          "  --post P             where a wall-eye's frame ends (patch means, equation 7, the\n"
          "                       8-bit codes): gpu (in shaders: only the patch means and the\n"
          "                       luminance statistics come back), cpu (the image read back),\n"
          "                       auto (default: gpu on a hardware GL with double-precision\n"
          "                       shaders, cpu on a software GL, where it measured faster; the\n"
          "                       ready line says which runs and why)\n"
          "  --no-compensation    no scattering compensation\n"
          "  --scene-config FILE  scene config (configs/scenes/) whose \"lcd\" block sets the LCD\n"
          "                       model as in `cave lcd` (panels, BRDF, content, white/black,\n"
          "                       texels, samples, tolerance; docs/scene-config.md); the\n"
          "                       --lcd-* options below override the block and every\n"
          "                       panel's own value\n"
          "  --lcd-size WxH       LCD texels of each panel (default lcd.resolution: 400 wide,\n"
          "                       height from the panel's aspect)\n"
          "  --lcd-spp N          samples per texel per round (default lcd.spp: 40)\n"
          "  --lcd-budget R       rounds per camera/lighting key (default 64)\n"
          "  --lcd-tolerance M    camera-key quantisation, 1e-5..1 m (default lcd.eye_tolerance: 0.005)\n"
          "  --lcd-content FILE   panel content image (default lcd.content: built-in test pattern)\n"
          "  --lcd-luminance L    panel white in cd/m2 (default lcd.content_luminance: 500)\n"
          "  --no-lcd             no LCD final gather\n"
          "  --no-idle-lcd        wall-eyes do not contribute LCD rounds\n"
          "  --lcd-wait           after the frames, wait until the LCD budget is summed\n"
          "  --seed N             LCD sample sequence seed, 0..4294967295 (default lcd.seed: 1)\n"
          "  --http ADDR:PORT     the live console (a web page: ranks, plots, images,\n"
          "                       controls; /metrics for Prometheus; docs/service.md) on\n"
          "                       this address (default 127.0.0.1:8033; PORT alone binds\n"
          "                       127.0.0.1; port 0: any free port, printed in the ready\n"
          "                       line; off: no console).  A port in use stops the start.\n"
          "                       An address outside 127.0.0.0/8 needs --http-token\n"
          "  --http-token FILE    every console request must carry the token on FILE's\n"
          "                       first line (16..255 characters): ?token=T or\n"
          "                       Authorization: Bearer T; else 401\n"
          "  --metrics FILE       JSON lines (default OUT/metrics.jsonl); its folder must exist\n"
          "                       (or be -o DIR)\n"
          "  --metrics-every K    write every K-th frame's metrics line (frames 0, K, 2K..;\n"
          "                       default 1: every frame); the ready and summary lines\n"
          "                       always\n"
          "  --metrics-max-mb M   rotate the metrics file before it would pass M MB (10^6\n"
          "                       bytes; default 512; 0: never): metrics.jsonl becomes\n"
          "                       metrics.1.jsonl, .1 becomes .2, ...; every file holds\n"
          "                       whole lines (docs/metrics.md \"Rotation\")\n"
          "  --metrics-keep N     rotated files kept (default 4; the oldest is deleted)\n"
          "  -o DIR               output folder, created when missing (default out/run)\n"
          "  --quiet              no per-frame lines\n"
          "  --check              check the configuration for --ranks N and print the\n"
          "                       rank layout, without MPI\n\n"
          "Under Open MPI as root add --allow-run-as-root; more ranks than cores need\n"
          "--oversubscribe.  SIGINT/SIGTERM to rank 0 (or mpirun) end the run after the\n"
          "current frame with every file whole.\n"
          "\nexamples:\n"
          "  cave run --check --ranks 11 configs/caves/cave5.json --scene scene.prt\n"
          "  mpirun -np 11 cave run configs/caves/cave5.json --scene scene.prt --frames 60 --dt 1/30 -o out\n"
          "  mpirun -np 11 cave run configs/caves/cave5.json --scene scene.prt --tracker configs/trackers/dtrack.json --present window\n");
}

/* Problems, one per line, collected for rank 0 to print. */
typedef struct problems {
  char buf[8192];
  size_t len;
  int n;
} problems;

static void problem(problems *p, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void problem(problems *p, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  if (p->len + 2 < sizeof p->buf) {
    int w = vsnprintf(p->buf + p->len, sizeof p->buf - p->len - 1, fmt, ap);
    if (w > 0) p->len += (size_t)w < sizeof p->buf - p->len - 1 ? (size_t)w : sizeof p->buf - p->len - 2;
    p->buf[p->len++] = '\n';
    p->buf[p->len] = 0;
  }
  va_end(ap);
  p->n++;
}

/* "files", "window", "desktop", "none" or a comma list of the others. */
static int parse_present(const char *v, unsigned *out) {
  char buf[64];
  if (strlen(v) >= sizeof buf) return -1;
  snprintf(buf, sizeof buf, "%s", v);
  unsigned p = 0;
  int none = 0, n = 0;
  for (char *save = NULL, *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save), n++) {
    if (!strcmp(t, "files")) p |= CV_PRESENT_FILES;
    else if (!strcmp(t, "window")) p |= CV_PRESENT_WINDOW;
    else if (!strcmp(t, "desktop")) p |= CV_PRESENT_DESKTOP;
    else if (!strcmp(t, "none")) none = 1;
    else return -1;
  }
  if (n == 0 || (none && n > 1)) return -1;
  *out = p;
  return 0;
}

/* An integer 0..4294967295, digits only. */
static int parse_u32(const char *s, unsigned long long *out) {
  if (!s || !*s || strlen(s) > 10) return -1;
  unsigned long long v = 0;
  for (const char *c = s; *c; c++) {
    if (*c < '0' || *c > '9') return -1;
    v = 10 * v + (unsigned long long)(*c - '0');
  }
  if (v > 4294967295ULL) return -1;
  *out = v;
  return 0;
}

/* --metrics-every K, --metrics-max-mb M, --metrics-keep N (docs/metrics.md,
 * "Cadence and rotation"); a bad value is a problem. */
static void parse_metrics_opt(const char *a, const char *v, cv_run_opts *o, problems *pb) {
  double d;
  if (!strcmp(a, "--metrics-every")) {
    if (cv_parse_int(v, 1, 1000000, &o->metrics_every)) problem(pb, "--metrics-every: expected K in 1..1000000, got '%s'", v);
  } else if (!strcmp(a, "--metrics-max-mb")) {
    if (cv_parse_double(v, &d) || !(d == 0 || (d >= 0.01 && d <= 1e6)))
      problem(pb, "--metrics-max-mb: expected 0 (never rotate) or 0.01..1000000 MB, got '%s'", v);
    else o->metrics_max_mb = d;
  } else if (!strcmp(a, "--metrics-keep")) {
    if (cv_parse_int(v, 1, 1000, &o->metrics_keep)) problem(pb, "--metrics-keep: expected N in 1..1000, got '%s'", v);
  }
}

#define NEED()                                                     \
  do {                                                             \
    if (!v) {                                                      \
      problem(pb, "%s: expected a value", a);                      \
      return -1;                                                   \
    }                                                              \
    ++*i;                                                          \
  } while (0)
#define PATH(field) snprintf(o->field, sizeof o->field, "%s", v)

/* One option of the service's modes and switches (argv[*i], its value v): 1 when taken (problems
 * recorded), 0 when not one of these, -1 when its value is missing. */
static int parse_mode_opt(const char *a, const char *v, int *i, cv_run_opts *o, int *check,
                          int *ranks, char *desktop_view, problems *pb) {
  double d;
  (void)check, (void)ranks, (void)desktop_view, (void)d;
  if (!strcmp(a, "--check")) {
    *check = 1;
  } else if (!strcmp(a, "--barrier")) {
    o->barrier = 1;
  } else if (!strcmp(a, "--no-predict")) {
    o->predict = 0;
  } else if (!strcmp(a, "--present")) {
    NEED();
    if (parse_present(v, &o->present))
      problem(pb, "--present: expected files, window, desktop, none or a comma list such as window,files, got '%s'", v);
  } else if (!strcmp(a, "--desktop-view")) {
    NEED();
    snprintf(desktop_view, CV_PATHLEN, "%s", v);
  } else if (!strcmp(a, "--desktop-fps")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d >= 0 && d <= 1000)) problem(pb, "--desktop-fps: expected 0..1000 (0: every frame), got '%s'", v);
    else o->desktop_fps = d;
  } else if (!strcmp(a, "--gpu")) {
    NEED();
    if (cv_gpu_parse(v, &o->gpu)) problem(pb, "--gpu: expected auto, software or a hardware device index 0..63, got '%s'", v);
  } else if (!strcmp(a, "--transfer")) {
    NEED();
    if (cv_render_transfer_parse(v, &o->half_transfer)) problem(pb, "--transfer: expected auto, float or half, got '%s'", v);
  } else if (!strcmp(a, "--clock")) {
    NEED();
    if (!strcmp(v, "wall")) o->clock = 1;
    else if (!strcmp(v, "sim")) o->clock = 0;
    else problem(pb, "--clock: expected wall or sim, got '%s'", v);
  } else if (!strcmp(a, "--share-lighting")) {
    NEED();
    if (!strcmp(v, "host")) o->share_lighting = CV_SHARE_HOST;
    else if (!strcmp(v, "host-now")) o->share_lighting = CV_SHARE_HOST_NOW;
    else if (!strcmp(v, "off")) o->share_lighting = CV_SHARE_OFF;
    else if (!strcmp(v, "background")) o->share_lighting = CV_SHARE_BACKGROUND;
    else if (!strcmp(v, "auto")) o->share_lighting = CV_SHARE_AUTO;
    else problem(pb, "--share-lighting: expected auto, host, host-now, background or off, got '%s'", v);
  } else if (!strcmp(a, "--swap-sync")) {
    NEED();
    if (!strcmp(v, "scheduled")) o->swap_sync = CV_SWAP_SCHEDULED;
    else if (!strcmp(v, "barrier")) o->swap_sync = CV_SWAP_BARRIER;
    else problem(pb, "--swap-sync: expected scheduled or barrier, got '%s'", v);
  } else if (!strcmp(a, "--swap-margin-ms")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d >= 0 && d <= 1000)) problem(pb, "--swap-margin-ms: expected 0..1000, got '%s'", v);
    else o->swap_margin_ms = d;
  } else if (!strcmp(a, "--predict-horizon")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d >= 0 && d <= 1)) problem(pb, "--predict-horizon: expected 0..1 s, got '%s'", v);
    else o->predict_horizon = d;
  } else if (!strcmp(a, "--quiet")) {
    o->quiet = 1;
  } else if (!strcmp(a, "--no-compensation")) {
    o->compensate = 0;
  } else if (!strcmp(a, "--no-lcd")) {
    o->lcd = 0;
  } else if (!strcmp(a, "--no-idle-lcd")) {
    o->lcd_idle = 0;
  } else if (!strcmp(a, "--lcd-wait")) {
    o->lcd_wait = 1;  } else {
    return 0;
  }
  return 1;
}

/* One option of inputs, outputs and the tracker (argv[*i], its value v): 1 when taken (problems
 * recorded), 0 when not one of these, -1 when its value is missing. */
static int parse_input_opt(const char *a, const char *v, int *i, cv_run_opts *o, int *check,
                           int *ranks, char *desktop_view, problems *pb) {
  double d;
  (void)check, (void)ranks, (void)desktop_view, (void)d;
  if (!strcmp(a, "--scene")) {
    NEED();
    PATH(scene_path);
  } else if (!strcmp(a, "--drive")) {
    NEED();
    PATH(drive_path);
  } else if (!strcmp(a, "--head-path")) {
    NEED();
    PATH(head_path);
  } else if (!strcmp(a, "--display")) {
    NEED();
    PATH(display_path);
  } else if (!strcmp(a, "--metrics")) {
    NEED();
    PATH(metrics_path);
  } else if (!strcmp(a, "--lcd-content")) {
    NEED();
    PATH(lcd_content);
  } else if (!strcmp(a, "--scene-config")) {
    NEED();
    PATH(scene_config);
  } else if (!strcmp(a, "-o")) {
    NEED();
    PATH(out_dir);
  } else if (!strcmp(a, "--tracker")) {
    NEED();
    PATH(tracker_path);
  } else if (!strcmp(a, "--http")) {
    NEED();
    cv_err e;
    if (cv_http_parse_listen(v, o->http_addr, sizeof o->http_addr, &o->http_port, &o->http_off, &e))
      problem(pb, "%s", e.msg);
  } else if (!strcmp(a, "--http-token")) {
    NEED();
    PATH(http_token_path);
  } else if (!strcmp(a, "--dtrack-host")) {
    NEED();
    snprintf(o->dtrack_host, sizeof o->dtrack_host, "%s", v);
  } else if (!strcmp(a, "--dtrack")) {
    NEED();
    if (cv_parse_int(v, 1, 65535, &o->dtrack_port)) problem(pb, "--dtrack: expected a UDP port 1..65535, got '%s'", v);
  } else if (!strcmp(a, "--dtrack-body")) {
    NEED();
    if (cv_parse_int(v, 0, 1000000, &o->dtrack_body)) problem(pb, "--dtrack-body: expected an id >= 0, got '%s'", v);  } else {
    return 0;
  }
  return 1;
}

/* One option of frames, timing and the compensation (argv[*i], its value v): 1 when taken (problems
 * recorded), 0 when not one of these, -1 when its value is missing. */
static int parse_frame_opt(const char *a, const char *v, int *i, cv_run_opts *o, int *check,
                           int *ranks, char *desktop_view, problems *pb) {
  double d;
  (void)check, (void)ranks, (void)desktop_view, (void)d;
  if (!strcmp(a, "--frames")) {
    NEED();
    if (cv_parse_int(v, 0, 100000000, &o->frames)) problem(pb, "--frames: expected N >= 0, got '%s'", v);
  } else if (!strcmp(a, "--ranks")) {
    NEED();
    if (cv_parse_int(v, 1, 100000, ranks)) problem(pb, "--ranks: expected N >= 1, got '%s'", v);
  } else if (!strcmp(a, "--dt")) {
    NEED();
    if (cv_parse_seconds(v, &d) || !(d > 0 && d <= 10)) problem(pb, "--dt: expected 0 < S <= 10 (0.0333 or 1/30), got '%s'", v);
    else o->dt = d;
  } else if (!strcmp(a, "--max-fps")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d > 0 && d <= 1000)) problem(pb, "--max-fps: expected 0 < F <= 1000, got '%s'", v);
    else o->max_fps = d;
  } else if (!strcmp(a, "--size")) {
    NEED();
    if (cv_parse_int(v, 8, 16384, &o->size)) problem(pb, "--size: expected 8..16384, got '%s'", v);
  } else if (!strcmp(a, "--metrics-every") || !strcmp(a, "--metrics-max-mb") || !strcmp(a, "--metrics-keep")) {
    NEED();
    parse_metrics_opt(a, v, o, pb);
  } else if (!strcmp(a, "--write-every")) {
    NEED();
    if (cv_parse_int(v, 0, 1000000, &o->write_every)) problem(pb, "--write-every: expected K >= 0, got '%s'", v);
  } else if (!strcmp(a, "--timeout-ms")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d >= 1 && d <= 3.6e6)) problem(pb, "--timeout-ms: expected 1..3600000, got '%s'", v);
    else o->timeout_ms = d;
  } else if (!strcmp(a, "--gather-timeout")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d >= 0.5 && d <= 3600)) problem(pb, "--gather-timeout: expected 0.5..3600 s, got '%s'", v);
    else o->gather_timeout_s = d;
  } else if (!strcmp(a, "--patches")) {
    NEED();
    if (cv_parse_int(v, 1, 256, &o->patches)) problem(pb, "--patches: expected 1..256, got '%s'", v);
  } else if (!strcmp(a, "--reflectance")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d >= 0 && d < 1)) problem(pb, "--reflectance: expected 0 <= R < 1 (as screens.reflectance), got '%s'", v);
    else o->reflectance = d;
  } else if (!strcmp(a, "--compensation-lag")) {
    NEED();
    if (cv_parse_int(v, 0, 1, &o->compensation_lag)) problem(pb, "--compensation-lag: expected 0 or 1 (frames), got '%s'", v);
  } else if (!strcmp(a, "--post")) {
    NEED();
    if (!strcmp(v, "auto")) o->post = CV_POST_AUTO;
    else if (!strcmp(v, "gpu")) o->post = CV_POST_GPU;
    else if (!strcmp(v, "cpu")) o->post = CV_POST_CPU;
    else problem(pb, "--post: expected auto, gpu or cpu, got '%s'", v);
  } else if (!strcmp(a, "--compensation-ms")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d > 0 && d <= 60000)) problem(pb, "--compensation-ms: expected 0 < T <= 60000, got '%s'", v);
    else o->compensation_ms = d;  } else {
    return 0;
  }
  return 1;
}

/* One option of the LCD readability figures (argv[*i], its value v): 1 when taken (problems
 * recorded), 0 when not one of these, -1 when its value is missing. */
static int parse_lcd_opt(const char *a, const char *v, int *i, cv_run_opts *o, int *check,
                         int *ranks, char *desktop_view, problems *pb) {
  double d;
  (void)check, (void)ranks, (void)desktop_view, (void)d;
  if (!strcmp(a, "--lcd-size")) {
    NEED();
    int w = 0, h = 0;
    char extra;
    if (sscanf(v, "%dx%d%c", &w, &h, &extra) != 2 || w < 1 || h < 1 || w > 4096 || h > 4096)
      problem(pb, "--lcd-size: expected WxH (1..4096), got '%s'", v);
    else o->lcd_w = w, o->lcd_h = h;
  } else if (!strcmp(a, "--lcd-spp")) {
    NEED();
    if (cv_parse_int(v, 1, 65536, &o->lcd_spp)) problem(pb, "--lcd-spp: expected 1..65536, got '%s'", v);
  } else if (!strcmp(a, "--lcd-budget")) {
    NEED();
    if (cv_parse_int(v, 1, 100000, &o->lcd_budget)) problem(pb, "--lcd-budget: expected 1..100000, got '%s'", v);
  } else if (!strcmp(a, "--lcd-tolerance")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d >= CV_LCD_TOLERANCE_MIN && d <= CV_LCD_TOLERANCE_MAX)) problem(pb, "--lcd-tolerance: expected 1e-5..1 m (as lcd.eye_tolerance), got '%s'", v);
    else o->lcd_tolerance = d;
  } else if (!strcmp(a, "--lcd-luminance")) {
    NEED();
    if (cv_parse_double(v, &d) || !(d >= 0 && d <= 1e6)) problem(pb, "--lcd-luminance: expected 0..1e6 cd/m2, got '%s'", v);
    else o->lcd_luminance = d;
  } else if (!strcmp(a, "--seed")) {
    NEED();
    unsigned long long u;
    if (parse_u32(v, &u)) problem(pb, "--seed: expected 0..4294967295 (as lcd.seed), got '%s'", v);
    else o->seed = (uint32_t)u, o->seed_set = 1;
  } else {
    return 0;
  }
  return 1;
}
#undef NEED
#undef PATH

static int parse(int argc, char **argv, cv_run_opts *o, int *check, int *ranks, char *desktop_view,
                 problems *pb) {
  static int (*const families[])(const char *, const char *, int *, cv_run_opts *, int *, int *,
                                 char *, problems *) = {parse_mode_opt, parse_input_opt,
                                                        parse_frame_opt, parse_lcd_opt};
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) return 1;
    int taken = 0;
    for (size_t k = 0; !taken && k < sizeof families / sizeof families[0]; k++) {
      taken = families[k](a, v, &i, o, check, ranks, desktop_view, pb);
      if (taken < 0) return -1;
    }
    if (taken) continue;
    if (a[0] == '-') {
      problem(pb, "unknown option '%s' (cave run --help lists them)", a);
    } else if (!o->cave_path[0]) {
      snprintf(o->cave_path, sizeof o->cave_path, "%s", a);
    } else {
      problem(pb, "unexpected argument '%s'", a);
    }
  }
  return 0;
}

static int file_readable(const char *p) {
  FILE *f = fopen(p, "rb");
  if (!f) return 0;
  fclose(f);
  return 1;
}

/* Loads the CAVE config, adding each of its problems; 1 when there were any. */
static int cave_problems(const char *path, cv_cave *cave, problems *pb) {
  char buf[8192];
  int n = 0;
  cv_err err;
  if (cv_cave_load_all(path, cave, buf, sizeof buf, &n, &err) == CV_OK) return 0;
  if (!buf[0]) {
    problem(pb, "%s", err.msg);
    return 1;
  }
  int listed = 0;
  for (char *save = NULL, *line = strtok_r(buf, "\n", &save); line; line = strtok_r(NULL, "\n", &save), listed++)
    problem(pb, "%s", line);
  for (; listed < n; listed++) problem(pb, "%s: (a further problem did not fit in the list)", path);
  return 1;
}

/* --present desktop: not with the walls' windows; --desktop-view names
 * cross or a wall (-> s->o.desktop_view). */
static void check_desktop(cv_service *s, const char *view, problems *pb) {
  cv_run_opts *o = &s->o;
  if (!(o->present & CV_PRESENT_DESKTOP)) {
    if (view[0]) problem(pb, "--desktop-view needs --present desktop");
    return;
  }
  if (o->present & CV_PRESENT_WINDOW)
    problem(pb, "--present desktop and window do not combine: desktop is the CAVE's stand-in on one "
            "screen, window drives the CAVE's projectors; use desktop or desktop,files");
  o->desktop_view = -1;
  if (!view[0] || !strcmp(view, "cross") || s->n_walls < 1) return;
  for (int w = 0; w < s->n_walls; w++)
    if (!strcmp(view, s->cave.walls[w].name)) {
      o->desktop_view = w;
      return;
    }
  char names[512] = "";
  for (int w = 0; w < s->n_walls; w++) {
    const size_t l = strlen(names);
    snprintf(names + l, sizeof names - l, ", %s", s->cave.walls[w].name);
  }
  problem(pb, "--desktop-view: expected cross or a wall of %s (%s), got '%s'", o->cave_path, names + 2, view);
}

/* Window outputs need an X display (the output's, or $DISPLAY) and a
 * stereo mode EGL can show: quad-buffered stereo is refused here as the run
 * would refuse it (cluster/walleye.c). */
static void check_present(cv_service *s, problems *pb) {
  if (!(s->o.present & CV_PRESENT_WINDOW)) return;
  const char *env = getenv("DISPLAY");
  for (int i = 0; i < s->cave.n_outputs; i++) {
    const char *wall = s->cave.walls[s->cave.outputs[i].wall].name;
    if (!s->cave.outputs[i].display[0] && !(env && env[0]))
      problem(pb, "--present window: outputs[%d] (wall %s) names no display and DISPLAY is not set", i, wall);
    if (s->cave.outputs[i].stereo == CV_STEREO_QUAD)
      problem(pb, "--present window: outputs[%d] (wall %s): quad-buffered stereo needs a stereo GL config, and EGL "
              "offers none: use \"passive\" (one output per eye) or \"side-by-side\"/\"top-bottom\"", i, wall);
  }
}

/* The LCD model (s->lcd, s->lcd_layout), the same as `cave lcd`'s: the
 * defaults, the scene config's lcd block, then the --lcd-* options; the
 * panels placed on the baked scene.  Sets o->lcd_w/h (the stacked buffer),
 * lcd_spp, lcd_tolerance, lcd_luminance from it.  Every rank runs this and
 * gets the same result. */
static void lcd_model(cv_service *s, int scene_ok, problems *pb) {
  cv_run_opts *o = &s->o;
  cv_lcd_config *c = &s->lcd;
  cv_err err;
  cv_lcd_config_default(c);
  if (o->scene_config[0]) {
    cv_scene_config sc;
    cv_scene_config_default(&sc);
    int st = cv_scene_config_load(o->scene_config, &sc, &err);
    cv_scene_config_free(&sc);
    if (st || cv_lcd_config_load_scene(o->scene_config, c, &err)) {
      problem(pb, "--scene-config: %s", err.msg);
      return;
    }
  } else if (o->scene_path[0] && file_readable(o->scene_path)) {
    /* the lcd block baked with the .prt (lcd_config.h), when there is one */
    uint64_t hash;
    int found;
    if (cv_prt_read_input_hash(o->scene_path, &hash, &err) == CV_OK &&
        cv_lcd_sidecar_load(o->scene_path, hash, c, &found, NULL, 0, &err)) {
      problem(pb, "--scene: %s", err.msg);
      return;
    }
  }
  if (o->lcd_w > 0) c->width = o->lcd_w, c->height = o->lcd_h;
  if (o->lcd_spp > 0) c->spp = o->lcd_spp;
  if (o->lcd_tolerance > 0) c->eye_tolerance = o->lcd_tolerance;
  if (o->lcd_content[0]) snprintf(c->content, sizeof c->content, "%s", o->lcd_content);
  if (o->seed_set) c->seed = o->seed;
  if (o->lcd_luminance >= 0) c->content_luminance = o->lcd_luminance;
  /* an option overrides the block and every panel's own value, as in cave lcd */
  cv_lcd_config_override(c, (o->lcd_w > 0 ? CV_LCD_SET_SIZE : 0u) |
                                (o->lcd_content[0] ? CV_LCD_SET_CONTENT : 0u) |
                                (o->lcd_luminance >= 0 ? CV_LCD_SET_WHITE : 0u));
  if (cv_lcd_config_panels(c, &err)) {
    problem(pb, "--scene-config: %s", err.msg);
    return;
  }
  for (int i = 0; i < c->n_panels; i++) {
    const char *b = c->panels[i].brdf;
    if (strncmp(b, "builtin:", 8) && !file_readable(b))
      problem(pb, "%s: lcd.panels[%d].brdf: %s: cannot open: %s", c->source[0] ? c->source : o->scene_config, i, b, strerror(errno));
  }
  o->lcd_spp = c->spp;
  o->lcd_tolerance = c->eye_tolerance;
  o->lcd_luminance = c->panels[0].content_luminance;
  if (!o->lcd || !o->scene_path[0] || !file_readable(o->scene_path)) return;
  cv_prt *prt = NULL;
  cv_mesh *m = NULL;
  if (cv_prt_read(o->scene_path, &prt, &err)) { /* the whole file, as the run reads it */
    if (scene_ok) problem(pb, "--scene: %s", err.msg);
    return;
  }
  if (cv_prt_to_mesh(prt, &m)) {
    problem(pb, "--scene: %s: cannot rebuild its mesh", o->scene_path);
  } else if (cv_lcd_layout_make(c, m, &s->lcd_layout, &err)) {
    if (o->scene_config[0]) problem(pb, "--scene-config: %s", err.msg);
    else problem(pb, "--scene: %s: %s (--no-lcd runs without the LCD)", o->scene_path, err.msg);
  } else {
    o->lcd_w = s->lcd_layout.W;
    o->lcd_h = s->lcd_layout.H;
    if (o->lcd_w > 4096 || o->lcd_h > 4096)
      problem(pb, "--lcd-size: the panels take %dx%d texels together (4096 x 4096 at most)", o->lcd_w,
              o->lcd_h);
    /* the content images as the run reads them: one that is no image fails here */
    cv_image *img = NULL;
    if (cv_lcd_layout_content(c, &s->lcd_layout, &img, &err))
      problem(pb, "%s: %s", o->lcd_content[0] ? "--lcd-content" : "--scene-config", err.msg);
    cv_image_destroy(img);
  }
  cv_mesh_destroy(m);
  cv_prt_destroy(prt);
}

/* -o (a folder, created when missing: not an existing file) and --metrics
 * (a file in a folder that exists, or in -o's), as the run opens them. */
static void check_outputs(const cv_run_opts *o, problems *pb) {
  struct stat st;
  if (stat(o->out_dir, &st) == 0 && !S_ISDIR(st.st_mode))
    problem(pb, "-o: %s: is a file, expected a folder (created when missing)", o->out_dir);
  if (!o->metrics_path[0]) return;
  if (stat(o->metrics_path, &st) == 0 && S_ISDIR(st.st_mode)) {
    problem(pb, "--metrics: %s: is a folder, expected a file", o->metrics_path);
    return;
  }
  char dir[CV_PATHLEN], outd[CV_PATHLEN];
  snprintf(dir, sizeof dir, "%s", o->metrics_path);
  snprintf(outd, sizeof outd, "%s", o->out_dir);
  const char *d = dirname(dir);
  size_t n = strlen(outd);
  while (n > 1 && outd[n - 1] == '/') outd[--n] = 0;
  if (!strcmp(d, outd)) return; /* -o's folder, created before the metrics open */
  if (stat(d, &st) != 0)
    problem(pb, "--metrics: cannot write %s: folder %s: %s", o->metrics_path, d, strerror(errno));
  else if (!S_ISDIR(st.st_mode))
    problem(pb, "--metrics: cannot write %s: %s is not a folder", o->metrics_path, d);
  else if (access(d, W_OK) != 0)
    problem(pb, "--metrics: cannot write %s: folder %s: %s", o->metrics_path, d, strerror(errno));
}

/* --http and --http-token: a readable token of the expected form; an
 * address off loopback only with a token; a token only with a console. */
static void check_http(const cv_run_opts *o, problems *pb) {
  if (o->http_off) {
    if (o->http_token_path[0]) problem(pb, "--http-token: no console to protect with --http off");
    return;
  }
  if (o->http_token_path[0]) {
    char tok[256];
    cv_err e;
    if (cv_http_load_token(o->http_token_path, tok, sizeof tok, &e)) problem(pb, "%s", e.msg);
  } else if (!cv_http_is_loopback(o->http_addr)) {
    problem(pb, "--http %s:%d: not a loopback address: anyone who reaches it could steer the CAVE; give "
            "--http-token FILE", o->http_addr, o->http_port);
  }
}

/* Every check that can be made before anything starts; fills s. */
static void check_all(cv_service *s, int size, const char *desktop_view, problems *pb) {
  cv_run_opts *o = &s->o;
  cv_err err;
  if (!o->cave_path[0]) {
    problem(pb, "no CAVE configuration given (cave run <cave.json> ...)");
  } else if (cave_problems(o->cave_path, &s->cave, pb)) {
    /* every problem of the file listed */
  } else {
    cv_cave_fit_res(&s->cave, o->size); /* --size: longer side, aspect kept (as cave render) */
    s->n_walls = s->cave.n_walls;
    s->n_walleyes = 2 * s->n_walls;
    s->n_render = s->cave.n_outputs;
    for (int a = 0; a < s->n_walls; a++)
      for (int b = a + 1; b < s->n_walls; b++) {
        const cv_wall *A = &s->cave.walls[a], *B = &s->cave.walls[b];
        if (!memcmp(A->pa, B->pa, sizeof A->pa) && !memcmp(A->pb, B->pb, sizeof A->pb) &&
            !memcmp(A->pc, B->pc, sizeof A->pc))
          problem(pb, "%s: walls[%d] ('%s') and walls[%d] ('%s') are the same screen", o->cave_path, a,
                  A->name, b, B->name);
      }
    if (cv_cave_check_eye(&s->cave, s->cave.head, &err)) problem(pb, "%s: head: %s", o->cave_path, err.msg);
    const int need = 1 + s->n_render;
    if (size < need)
      problem(pb, "%d ranks: %s has %d walls shown by %d outputs, so the service needs at least "
              "1 + %d = %d ranks (master + one per output); extra ranks path-trace the LCD", size,
              o->cave_path, s->n_walls, s->n_render, s->n_render, need);
    else
      s->n_gather = size - need;
  }
  int scene_ok = 0; /* the header and the file's size read; the whole file is read with the LCD model */
  if (!o->scene_path[0]) {
    problem(pb, "--scene: a baked scene (.prt) is required (cave bake makes one)");
  } else if (!file_readable(o->scene_path)) {
    problem(pb, "--scene: %s: cannot open: %s", o->scene_path, strerror(errno));
  } else {
    uint64_t h;
    /* the header and its counts against the file's size (a truncated file) */
    if (cv_prt_read_input_hash(o->scene_path, &h, &err)) problem(pb, "--scene: %s", err.msg);
    else scene_ok = 1;
  }
  if (o->drive_path[0]) {
    char buf[4096];
    int np = 0;
    if (cv_drive_validate_all(o->drive_path, buf, sizeof buf, &np) != CV_OK) {
      char *line = strtok(buf, "\n");
      for (; line; line = strtok(NULL, "\n")) problem(pb, "--drive: %s", line);
    } else if (cv_drive_load(o->drive_path, &s->drive, &err)) {
      problem(pb, "--drive: %s", err.msg);
    }
  } else if (cv_drive_parse(k_builtin_drive, "(built-in drive)", NULL, &s->drive, &err)) {
    problem(pb, "built-in drive: %s (is blender-data installed?)", err.msg);
  }
  if (o->head_path[0]) {
    cv_head_path *hp;
    if (cv_head_path_load(o->head_path, &hp, &err)) problem(pb, "--head-path: %s", err.msg);
    else cv_head_path_destroy(hp);
  }
  if (o->tracker_path[0]) {
    cv_tracker_config tc;
    if (cv_tracker_config_load(o->tracker_path, &tc, &err)) problem(pb, "--tracker: %s", err.msg);
    else if (o->dtrack_port > 0) problem(pb, "--tracker and --dtrack: give one head source");
    else if (!o->head_path[0]) o->dtrack_port = tc.port; /* the master opens it as configured */
  }
  if (o->head_path[0] && o->dtrack_port > 0)
    problem(pb, "--head-path and --dtrack: give one head source");
  if (o->head_path[0] && o->tracker_path[0])
    problem(pb, "--head-path and --tracker: give one head source");
  if (o->display_path[0] && !o->compensate)
    problem(pb, "--display and --no-compensation contradict each other");
  if (o->lcd_content[0] && !file_readable(o->lcd_content))
    problem(pb, "--lcd-content: %s: cannot open: %s", o->lcd_content, strerror(errno));
  lcd_model(s, scene_ok, pb);
  if (s->n_walls > 0 && o->compensate) {
    cv_display *d;
    if (cv_service_display(s, &d, &err)) problem(pb, "--display: %s", err.msg);
    else cv_display_destroy(d);
  }
  if (s->n_walls > 0) check_present(s, pb);
  check_desktop(s, desktop_view, pb);
  if (!o->out_dir[0]) snprintf(o->out_dir, sizeof o->out_dir, "out/run");
  check_outputs(o, pb);
  check_http(o, pb);
  if (o->dtrack_host[0]) {
    struct in_addr ia;
    if (inet_pton(AF_INET, o->dtrack_host, &ia) != 1)
      problem(pb, "--dtrack-host: '%s' is not an IPv4 address (expected a.b.c.d)", o->dtrack_host);
  }
  if (o->clock < 0) o->clock = (o->present & (CV_PRESENT_WINDOW | CV_PRESENT_DESKTOP)) ? 1 : 0;
  o->swap_lock = o->barrier || (o->present & CV_PRESENT_WINDOW);
}

static void print_layout(const cv_service *s, int ranks) {
  printf("cave run: %d ranks: rank 0 master", ranks);
  if (s->o.present & CV_PRESENT_DESKTOP)
    printf(", desktop preview on $DISPLAY (%s)",
           s->o.desktop_view < 0 ? "cross" : s->cave.walls[s->o.desktop_view].name);
  printf("\n");
  for (int i = 0; i < s->cave.n_outputs; i++) {
    const cv_output *o = &s->cave.outputs[i];
    char gpu[16];
    const int g = s->o.gpu != CV_GPU_UNSET ? s->o.gpu : o->gpu;
    if (g == CV_GPU_AUTO) snprintf(gpu, sizeof gpu, "auto");
    else if (g == CV_GPU_SOFTWARE) snprintf(gpu, sizeof gpu, "software");
    else snprintf(gpu, sizeof gpu, "%d", g);
    printf("  rank %d: wall %s, %s, host %s, display %s, ", 1 + i, s->cave.walls[o->wall].name,
           o->eyes == 3 ? cv_stereo_mode_name(o->stereo) : (o->eyes == 1 ? "left eye" : "right eye"),
           o->host[0] ? o->host : "(any)", o->display[0] ? o->display : "$DISPLAY");
    if (o->fullscreen) printf("fullscreen");
    else if (o->geometry[2]) printf("%dx%d+%d+%d", o->geometry[2], o->geometry[3], o->geometry[0], o->geometry[1]);
    else printf("tiled");
    printf(", gpu %s\n", gpu);
  }
  if (s->n_gather) printf("  ranks %d-%d: gather-only\n", 1 + s->n_render, ranks - 1);
  if (s->o.lcd && s->lcd_layout.n > 0) { /* the LCD model (docs/readability.md) */
    printf("  LCD (%s%s):", s->o.scene_config[0] ? s->o.scene_config
                            : s->lcd.source[0] ? s->lcd.source : "defaults: ",
           s->o.scene_config[0] || s->lcd.source[0] ? "" : "the .prt has no lcd block");
    for (int i = 0; i < s->lcd_layout.n; i++)
      printf("%s %s %dx%d", i ? "," : "", s->lcd.panels[i].name, s->lcd_layout.w[i], s->lcd_layout.h[i]);
    printf(" texels, %d spp per round, eye tolerance %g m\n", s->o.lcd_spp, s->o.lcd_tolerance);
  }
  if (s->o.http_off) printf("  console: off (--http off)\n");
  else if (s->o.http_port == 0) printf("  console: http://%s:<any free port>/ (the ready line says which)%s\n", s->o.http_addr,
                                       s->o.http_token_path[0] ? ", token required" : "");
  else printf("  console: http://%s:%d/%s\n", s->o.http_addr, s->o.http_port,
              s->o.http_token_path[0] ? ", token required" : "");
}

static int mkdirs(const char *path) {
  char tmp[CV_PATHLEN];
  snprintf(tmp, sizeof tmp, "%s", path);
  for (char *p = tmp + 1; *p; p++)
    if (*p == '/') {
      *p = 0;
      if (mkdir(tmp, 0777) && errno != EEXIST) return -1;
      *p = '/';
    }
  if (mkdir(tmp, 0777) && errno != EEXIST) return -1;
  struct stat st;
  if (stat(tmp, &st) != 0) return -1;
  if (!S_ISDIR(st.st_mode)) { /* EEXIST on a plain file is no folder */
    errno = ENOTDIR;
    return -1;
  }
  return 0;
}

int cmd_run(int argc, char **argv) {
  cv_service s;
  memset(&s, 0, sizeof s);
  cv_run_opts_default(&s.o);
  s.stop = &g_stop;
  problems pb;
  memset(&pb, 0, sizeof pb);
  int check = 0, ranks = 0;
  char desktop_view[CV_PATHLEN] = "";
  int h = parse(argc, argv, &s.o, &check, &ranks, desktop_view, &pb);
  if (h == 1) {
    help(stdout);
    return 0;
  }
  if (check) {
    if (ranks < 1) problem(&pb, "--check needs --ranks N");
    check_all(&s, ranks, desktop_view, &pb);
    if (pb.n) {
      fputs(pb.buf, stderr);
      fprintf(stderr, "cave run: %d problem%s, not started\n", pb.n, pb.n > 1 ? "s" : "");
      cv_drive_destroy(s.drive);
      return 2;
    }
    print_layout(&s, ranks);
    cv_drive_destroy(s.drive);
    return 0;
  }
  if (cv_comm_init(&argc, &argv, &s.rank, &s.size)) {
    fprintf(stderr, "cave run: MPI_Init failed\n");
    return 1;
  }
  cv_comm_set_stop_flag(&g_stop); /* a rank declared dead leaves (docs/dead-rank.md) */
  cv_comm_set_master_timeout(2 * s.o.gather_timeout_s); /* the master's host gone */
  check_all(&s, s.size, desktop_view, &pb);
  if (!pb.n && mkdirs(s.o.out_dir)) problem(&pb, "-o: %s: cannot create: %s", s.o.out_dir, strerror(errno));
  if (pb.n) {
    if (s.rank == 0) {
      fputs(pb.buf, stderr);
      fprintf(stderr, "cave run: %d problem%s, not started\n", pb.n, pb.n > 1 ? "s" : "");
    }
    cv_drive_destroy(s.drive);
    cv_comm_finalize();
    return 2;
  }
  /* One run per out folder (issue 35, defect 6): rank 0 locks it before any
   * rank writes there (pid files included); a second run refuses. */
  int lock_fd = -1;
  {
    cv_err lerr;
    cv_err_clear(&lerr);
    const int busy = cv_comm_bcast_int(s.rank == 0 && cv_dirlock_take(s.o.out_dir, &lock_fd, &lerr) != CV_OK);
    if (busy) {
      if (s.rank == 0) fprintf(stderr, "cave run: %s; not started\n", lerr.msg);
      cv_drive_destroy(s.drive);
      cv_comm_finalize();
      return 1;
    }
  }
  /* Each rank's pid, for operators (and the fault tests: SIGSTOP a rank);
   * removed again on a clean exit. */
  char pd[CV_PATHLEN + 32], pf[CV_PATHLEN + 64];
  pf[0] = 0;
  {
    snprintf(pd, sizeof pd, "%s/pids", s.o.out_dir);
    if (!mkdirs(pd)) {
      snprintf(pf, sizeof pf, "%s/rank%d.pid", pd, s.rank);
      FILE *f = fopen(pf, "w");
      if (f) {
        fprintf(f, "%ld\n", (long)getpid());
        fclose(f);
      }
    }
  }
  s.n_contributors = s.o.lcd ? (s.o.lcd_idle ? s.n_render : 0) + s.n_gather : 0;
  if (s.o.lcd && s.n_contributors == 0) s.o.lcd = 0; /* nobody to path-trace the LCD */
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
  const cv_rank_role role = cv_cave_rank_role(&s.cave, s.rank);
  if (cv_comm_render_group(role.role == CV_ROLE_RENDER)) {
    fprintf(stderr, "cave run: rank %d: cannot create the render ranks' communicator\n", s.rank);
    cv_comm_abort(1, NULL);
  }
  /* The LCD allreduce: the master and the gather-only ranks (lcdreduce.c). */
  const int lcd_member = s.o.lcd && s.n_gather > 0 && role.role != CV_ROLE_RENDER;
  if (cv_comm_lcd_group(lcd_member, &s.lcd_members, &s.lcd_me)) {
    fprintf(stderr, "cave run: rank %d: cannot create the LCD reduction's communicator\n", s.rank);
    cv_comm_abort(1, NULL);
  }
  int rc;
  if (role.role == CV_ROLE_MASTER) {
    rc = cv_master_run(&s);
    cv_dirlock_release(s.o.out_dir, lock_fd);
  }
  else if (role.role == CV_ROLE_RENDER) rc = cv_walleye_run(&s);
  else rc = cv_gather_run(&s);
  cv_drive_destroy(s.drive);
  cv_comm_finalize();
  if (rc == 0 && pf[0]) {
    remove(pf);
    rmdir(pd); /* the last rank out removes the folder (others' files: ENOTEMPTY) */
  }
  if (s.rank == 0) cv_comm_end_job(rc);
  return rc;
}
