/* Render ranks: rank 1 + i shows outputs[i] of the CAVE config (view/cave.h):
 * one eye of a wall (passive stereo) or both eyes of a wall in one window
 * (side-by-side, top-bottom; quad-buffered is refused: EGL has no stereo
 * configs).  Per frame, as named phases:
 *   take the master's frame state; relight when the light key changed;
 *   render each eye (depth, PRT shading tone-mapped with the shared
 *     adaptation, display-linear; the HDR image downsampled to the
 *     luminance image of the foveal statistics: no luminance pass);
 *   report each eye (statistics, patch means, the previous frame's swap
 *     time and frame-path counters) to the master; on desktop preview
 *     frames the left eye also sends its uncompensated tone-mapped image
 *     as 8-bit codes;
 *   apply the master's scattering correction for this wall with equation
 *     7: frame N - lag's (--compensation-lag; the last one when it does not
 *     come within --timeout-ms / 2, counted as late);
 *   present: the 8-bit projector image drawn into the window, glFinish,
 *     the swap-lock barrier among all render ranks, swap, stamp;
 *   write the frame's files when the master marks it.
 * With --post gpu (auto where the GL can) the frame ends on the GPU
 * (render/renderer.h, "the frame on the GPU"): the display image, equation
 * 7 and the codes stay in the GL, only the patch means and the luminance
 * statistics come back; images are read back only on frames that write
 * files or desktop previews.  With --post cpu the display image comes back
 * and equation 7 and the codes run here (compensate/resample.h).
 * While waiting it answers the master's clock probes, does LCD rounds in an
 * idle thread, takes LCD images, and watches its window: Escape, a closed
 * window or a lost X connection is sent to the master, which stops every
 * rank; this rank keeps its place in the barriers until then. */
#include <math.h>
#include <signal.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "compensate/resample.h"
#include "core/hash.h"
#include "io/exr.h"
#include "io/filewriter.h"
#include "io/png.h"
#include "lcd/gather.h"
#include "lcdwork.h"
#include "lightshare.h"
#include "render/renderer.h"
#include "render/window.h"
#include "service_internal.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"
#include "view/offaxis.h"

/* Wall-eyes of at most this many shaded pixels skip the z pre-pass
 * (opts.depth_less), see walleye_setup. */
#define CV_WALLEYE_ONE_PASS_PIXELS (720L * 720L)

static int send_to_master(const uint8_t *buf, size_t len, void *user) {
  (void)user;
  return cv_comm_send(buf, len, 0, CV_TAG_LCD);
}

/* One eye of the output. */
typedef struct eye_view {
  int eye;              /* 0 left, 1 right */
  int slot;             /* the renderer's projector image of this eye (--post gpu) */
  int failed;           /* this frame: no image (head behind the wall, GL error) */
  cv_image *disp_img;   /* uncompensated display-linear (Drago, no transfer) */
  cv_image *hdr, *lum;
  cv_image *out;        /* compensated display-linear: what the projector gets */
  uint8_t *code;        /* 3 w h: out as 8-bit Rec.709 codes (window and PNG) */
  double *patch;        /* 3 np: patch means of disp_img */
} eye_view;

typedef struct walleye {
  cv_service *s;
  const cv_output *o;
  int wall, n_eyes;
  eye_view ev[2];
  cv_prt *prt;
  cv_renderer *r;
  cv_lcd_worker *lw;
  cv_display *disp;
  const cv_display_surface *S;
  int w, h;
  float *delta;       /* 3 np: last correction */
  int have_delta;
  uint32_t corr_frame; /* its frame (0xffffffff: none) */
  float *pend;        /* 3 np: a correction of a later frame, kept for that frame */
  uint32_t pend_frame; /* its frame (0xffffffff: none) */
  int gpu_post;       /* 1: the frame ends on the GPU (--post) */
  char post_why[sizeof(((cv_err *)0)->msg)]; /* --post auto chose the CPU: why */
  /* the frame path (reported with the next frame): thread CPU ms inside GL
   * calls, in the relight and the waits; the last frame's figures; the GL
   * counters at the last report */
  double cpu_gl, cpu_skip;
  double prev_cpu, prev_gpu, prev_wait;
  uint32_t prev_corr;
  uint64_t io_read_rep, io_up_rep;
  double cpu_drawn;   /* thread CPU ms when the present's draw returned */
  cv_filewriter *fw;  /* --present files: the writer thread (NULL: no files) */
  uint64_t files_nomem; /* a written frame's files not queued: no memory for the copies */
  uint64_t light_key;
  int have_light;
  cv_lightshare ls;   /* --share-lighting (lightshare.h) */
  cv_mailbox *state_mb, *corr_mb, *lcdimg_mb, *ping_mb, *go_mb;
  uint64_t lcd_rounds_done;
  double lcd_ms;
  uint64_t late_corr;
  int have_panel;
  cv_lcd_panel panel;
  cv_lightmix *mix;
  cv_rec709_lut lut;
  cv_window_spec spec;
  char title[96];
  int win_event;      /* CV_WIN_* sent to the master (once) */
  double sig_since;   /* when this rank's stop flag (a signal) was first seen; 0 never */
  int sig_sent;       /* the signal's stop request went to the master */
  int files_said;     /* the first failed file was said on stderr */
  /* the last swap, reported with the next frame */
  uint32_t swap_frame;
  double swap_t, ms_present, ms_barrier;
} walleye;

static void walleye_free(walleye *we) {
  cv_filewriter_destroy(we->fw); /* first: its jobs read the LUT */
  cv_lcd_worker_destroy(we->lw);
  cv_lightmix_destroy(we->mix);
  cv_renderer_destroy(we->r);
  cv_prt_destroy(we->prt);
  cv_display_destroy(we->disp);
  for (int k = 0; k < 2; k++) {
    eye_view *v = &we->ev[k];
    cv_image_destroy(v->disp_img);
    cv_image_destroy(v->hdr);
    cv_image_destroy(v->lum);
    cv_image_destroy(v->out);
    free(v->code);
    free(v->patch);
  }
  free(we->delta);
  free(we->pend);
  cv_mailbox_close(we->state_mb);
  cv_mailbox_close(we->corr_mb);
  cv_mailbox_close(we->lcdimg_mb);
  cv_mailbox_close(we->ping_mb);
  cv_mailbox_close(we->go_mb);
}

/* Where the window goes: the output's geometry, fullscreen, or (neither
 * given) tiled five to a row in output order at the rendered size. */
static void window_spec(walleye *we) {
  const cv_output *o = we->o;
  cv_window_spec *sp = &we->spec;
  memset(sp, 0, sizeof *sp);
  sp->display = o->display;
  sp->fullscreen = o->fullscreen;
  const int idx = we->s->rank - 1;
  const int ww = we->w * (o->stereo == CV_STEREO_SIDE_BY_SIDE ? 2 : 1);
  const int wh = we->h * (o->stereo == CV_STEREO_TOP_BOTTOM ? 2 : 1);
  if (o->geometry[2] > 0) {
    sp->x = o->geometry[0], sp->y = o->geometry[1], sp->w = o->geometry[2], sp->h = o->geometry[3];
  } else {
    sp->x = (idx % 5) * ww, sp->y = (idx / 5) * wh, sp->w = ww, sp->h = wh;
  }
  snprintf(we->title, sizeof we->title, "cave %s %s (rank %d)", we->s->cave.walls[we->wall].name,
           o->eyes == 3 ? cv_stereo_mode_name(o->stereo) : (o->eyes == 1 ? "L" : "R"), we->s->rank);
  sp->title = we->title;
}

static int eye_setup(walleye *we, eye_view *v, int eye, size_t np, cv_err *err) {
  v->eye = eye;
  if (cv_image_create(we->w, we->h, 3, &v->disp_img) || cv_image_create(we->w, we->h, 3, &v->hdr) ||
      cv_image_create(we->w, we->h, 3, &v->out) ||
      cv_image_create(we->s->cave.lum_res, we->s->cave.lum_res, 1, &v->lum) ||
      !(v->code = malloc(3 * (size_t)we->w * we->h)) || (np && !(v->patch = calloc(3 * np, sizeof *v->patch))))
    return cv_err_set(err, CV_ERR_NOMEM, "render rank: out of memory");
  return CV_OK;
}

/* Thread CPU ms (the frame path's own work, whatever else the host runs). */
static double thread_cpu_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* --post: the GPU where asked, or (auto) on a hardware GL with
 * double-precision shaders and no more patches than pixels (on a software GL
 * the CPU path measured faster); the reason for the CPU is kept for the
 * ready line.  --post gpu on a GL that cannot is an
 * error naming why. */
static int choose_post(walleye *we, cv_err *err) {
  const int want = we->s->o.post;
  if (want == CV_POST_CPU) {
    snprintf(we->post_why, sizeof we->post_why, "--post cpu");
    return CV_OK;
  }
  char why[sizeof err->msg];
  if (want == CV_POST_AUTO && cv_renderer_is_software(we->r)) {
    /* measured (docs/benchmarks.md, "The frame on the GPU"): on llvmpipe the
     * shader passes cost more CPU than the read-back and the CPU's loops */
    snprintf(we->post_why, sizeof we->post_why, "--post auto on a software GL: the CPU path measured faster on "
             "llvmpipe (27.3 against 12.3 CAVE frames/s at 240^2 on 2 cores)");
    return CV_OK;
  }
  if (cv_renderer_post_available(we->r, why, sizeof why)) {
    const int nu = we->S ? we->S->nu : 1, nv = we->S ? we->S->nv : 1;
    int st = cv_renderer_post_grid(we->r, nu, nv, we->S ? we->S->edge_u : NULL, we->S ? we->S->edge_v : NULL,
                                   we->w, we->h, err);
    if (st == CV_OK) {
      we->gpu_post = 1;
      /* a GPU frame is not cut by a glFinish per pass: its time comes from a timer query */
      if (!cv_renderer_is_software(we->r)) cv_renderer_set_timing(we->r, 0);
      return CV_OK;
    }
    snprintf(why, sizeof why, "%s", err->msg);
  }
  if (want == CV_POST_GPU)
    return cv_err_set(err, CV_ERR_BACKEND, "outputs[%d] (wall %s): --post gpu: %s", we->s->rank - 1,
                      we->s->cave.walls[we->wall].name, why);
  snprintf(we->post_why, sizeof we->post_why, "%s", why);
  return CV_OK;
}

static int walleye_setup(walleye *we, cv_err *err) {
  cv_service *s = we->s;
  const cv_rank_role role = cv_cave_rank_role(&s->cave, s->rank);
  we->o = &s->cave.outputs[role.output];
  we->wall = we->o->wall;
  const cv_wall *W = &s->cave.walls[we->wall];
  we->w = W->res[0]; /* --size already applied, aspect kept (cv_cave_fit_res) */
  we->h = W->res[1];
  we->swap_frame = 0xffffffffu;
  cv_rec709_lut_init(&we->lut);
  const int window = (s->o.present & CV_PRESENT_WINDOW) != 0;
  if (window && we->o->stereo == CV_STEREO_QUAD)
    return cv_err_set(err, CV_ERR_BACKEND,
                      "outputs[%d] (wall %s): quad-buffered stereo needs a stereo GL config, and EGL "
                      "offers none (no EGL stereo attribute exists; Mesa's GLX has no stereo visuals "
                      "either): use \"passive\" (one output per eye) or \"side-by-side\"/\"top-bottom\"",
                      role.output, W->name);
  cv_service_test_load_delay(s->rank);
  int st = cv_prt_read(s->o.scene_path, &we->prt, err);
  if (st) return st;
  cv_render_opts ro;
  cv_render_default_opts(&ro);
  ro.timing = 1;
  ro.display_float = 1; /* display-linear values in float: equation 7 and the codes from them */
  ro.cull_back = -1; /* on when the scene is closed and consistently wound */
  /* Small wall-eyes shade in one depth-LESS pass: the z pre-pass is a whole
   * geometry pass, which at 360^2 costs more than shading the overdraw
   * (docs/benchmarks.md, "Where a CAVE frame's time goes"). */
  ro.depth_less = (long)we->w * we->h * s->cave.supersample * s->cave.supersample <= CV_WALLEYE_ONE_PASS_PIXELS;
  ro.gpu = s->o.gpu != CV_GPU_UNSET ? s->o.gpu : we->o->gpu;
  ro.half_transfer = s->o.half_transfer;
  if (window) {
    window_spec(we);
    ro.window = &we->spec;
  }
  st = cv_renderer_create(we->prt, &ro, &we->r, err);
  if (st) return st;
  cv_render_tex_info ti;
  cv_renderer_textures(we->r, &ti);
  if (ti.unread) /* shown with their mean albedo (renderer.h) */
    fprintf(stderr, "cave run: rank %d: warning: %d textures could not be read and show their mean "
            "albedo; first: %s\n", we->s->rank, ti.unread, ti.first_error);
  st = cv_service_lightmix(s, (int)we->prt->bands, &we->mix, err);
  if (st) return st;
  size_t np = 0;
  if (s->o.compensate) {
    st = cv_service_display(s, &we->disp, err);
    if (st) return st;
    we->S = cv_display_surface_at(we->disp, (size_t)we->wall);
    np = (size_t)we->S->nu * we->S->nv;
    we->delta = calloc(3 * np, sizeof *we->delta);
    we->pend = calloc(3 * np, sizeof *we->pend);
    if (!we->delta || !we->pend) return cv_err_set(err, CV_ERR_NOMEM, "render rank: out of memory");
    we->corr_mb = cv_mailbox_open(0, CV_TAG_CORR, sizeof(cv_patch_msg) + 3 * np * sizeof(float));
    if (!we->corr_mb) return cv_err_set(err, CV_ERR_NOMEM, "render rank: cannot post receives");
  }
  for (int e = 0; e < 2; e++)
    if (we->o->eyes >> e & 1) {
      we->ev[we->n_eyes].slot = we->n_eyes;
      st = eye_setup(we, &we->ev[we->n_eyes++], e, np, err);
      if (st) return st;
    }
  /* files only when asked (--present files): two frames of this output's eyes may wait,
   * written by a thread at nice 10 (io/filewriter.c), so writing does not lengthen frames */
  if ((s->o.present & CV_PRESENT_FILES) && (st = cv_filewriter_create(2 * we->n_eyes, 1, &we->fw, err))) return st;
  we->corr_frame = we->pend_frame = we->prev_corr = 0xffffffffu;
  we->prev_gpu = -1;
  if ((st = choose_post(we, err))) return st;
  if (s->o.lcd && s->lcd_layout.n > 0) {
    /* The first panel's frame, to show its part of the LCD image on it (the
     * renderer shows one panel). */
    we->panel = s->lcd_layout.rect[0];
    we->have_panel = 1;
  }
  const int index = cv_service_contributor(s, s->rank);
  if (index >= 0) {
    st = cv_lcd_worker_create(s, we->prt, index, 1, &we->lw, err);
    if (st) return st;
  }
  we->state_mb = cv_mailbox_open(0, CV_TAG_STATE, CV_FRAME_STATE_BYTES);
  we->ping_mb = cv_mailbox_open(0, CV_TAG_PING, sizeof(double));
  we->go_mb = cv_mailbox_open(0, CV_TAG_GO, 2 * sizeof(double));
  we->lcdimg_mb = cv_mailbox_open(0, CV_TAG_LCDIMG,
                                  sizeof(cv_lcdimg_msg) + 3 * (size_t)s->o.lcd_w * s->o.lcd_h * sizeof(float));
  if (!we->state_mb || !we->lcdimg_mb || !we->ping_mb || !we->go_mb)
    return cv_err_set(err, CV_ERR_NOMEM, "render rank: cannot post receives");
  return CV_OK;
}

/* Clock probes: echo t0 with this rank's receive and send times. */
static void answer_pings(walleye *we) {
  const uint8_t *data;
  long len;
  while ((len = cv_mailbox_take(we->ping_mb, &data, NULL)) >= 0) {
    const double t1 = cv_service_now();
    if (len != sizeof(double)) continue;
    double msg[3];
    memcpy(&msg[0], data, sizeof(double));
    msg[1] = t1;
    msg[2] = cv_service_now();
    cv_comm_send(msg, sizeof msg, 0, CV_TAG_PONG);
  }
}

/* The window: an operator's Escape or close, or a lost X connection, goes
 * to the master once; it stops every rank. */
static void watch_window(walleye *we) {
  if (!we->r || we->win_event) return;
  const int ev = cv_renderer_window_poll(we->r);
  if (ev == CV_WIN_OK) return;
  we->win_event = ev;
  char msg[256];
  const char *dpy = we->spec.display && we->spec.display[0] ? we->spec.display : getenv("DISPLAY");
  snprintf(msg, sizeof msg, "%c rank %d (wall %s, %s, X display '%s'): %s", '0' + ev, we->s->rank,
           we->s->cave.walls[we->wall].name, we->o->eyes == 3 ? "both eyes" : (we->o->eyes == 1 ? "left eye" : "right eye"),
           dpy ? dpy : "(unset)", cv_window_event_name(ev));
  cv_comm_send(msg, strlen(msg) + 1, 0, CV_TAG_STOPREQ);
}

/* A signal to this rank alone (issue 35, defect 4): it went on with its
 * waits cut short, a frame ahead of the others, and nobody said anything.
 * Once its stop flag has been set for 0.5 s without the master's quit (a
 * signal to the whole job makes the master quit first), it asks the master
 * to stop the run, naming itself; the master stops every rank (summary
 * stop_reason, exit status 1).  Not for a rank declared dead (it leaves). */
static void watch_signal(walleye *we) {
  cv_service *s = we->s;
  if (!*s->stop || we->sig_sent || cv_comm_declared_dead()) return;
  const double now = cv_service_now();
  if (we->sig_since == 0) we->sig_since = now;
  if (now - we->sig_since < 0.5) return;
  we->sig_sent = 1;
  const int sig = *s->stop;
  char msg[256];
  snprintf(msg, sizeof msg, "S rank %d (wall-eye of wall %s) got %s: the run stops", s->rank,
           s->cave.walls[we->wall].name, sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a stop signal");
  fprintf(stderr, "cave run: rank %d: %s alone (not the job): asking the master to stop the run\n", s->rank,
          sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a stop signal");
  cv_comm_send(msg, strlen(msg) + 1, 0, CV_TAG_STOPREQ);
}

/* Background work while waiting: clock probes, the window, a signal, LCD
 * rounds out, LCD images in. */
static void idle(walleye *we) {
  answer_pings(we);
  watch_window(we);
  watch_signal(we);
  if (we->lw) cv_lcd_worker_send_ready(we->lw, send_to_master, NULL, &we->lcd_rounds_done, &we->lcd_ms);
  const uint8_t *data;
  long len;
  while ((len = cv_mailbox_take(we->lcdimg_mb, &data, NULL)) >= 0) {
    cv_lcdimg_msg h;
    if ((size_t)len < sizeof h) continue;
    memcpy(&h, data, sizeof h);
    if ((size_t)len != sizeof h + 3 * (size_t)h.w * h.h * sizeof(float)) continue;
    cv_image img = {.w = h.w, .h = h.h, .c = 3, .px = (float *)(void *)(uintptr_t)(data + sizeof h)};
    /* the first panel: the top rows of the stacked image (lcd/panels.h),
     * as wide as the image when the first panel is the widest */
    if (we->s->lcd_layout.n > 0 && h.w == we->s->lcd_layout.W && h.h == we->s->lcd_layout.H &&
        we->s->lcd_layout.w[0] == h.w)
      img.h = we->s->lcd_layout.h[0];
    cv_err err;
    if (we->have_panel &&
        cv_renderer_set_panel(we->r, we->panel.center, we->panel.u, we->panel.v, we->panel.size, &img, &err))
      fprintf(stderr, "cave run: rank %d: LCD image: %s\n", we->s->rank, err.msg);
  }
  cv_comm_progress();
}

static void nap(void) {
  /* 0.5 ms: ten ranks polling on two cores must leave them to the others */
  struct timespec ts = {0, 500000};
  nanosleep(&ts, NULL);
}

/* Waits for the next frame state; 1 = got one, 0 = quit.  *hash: FNV-1a
 * of the bytes received (echoed to the master, which checks that every rank
 * rendered with the state it sent). */
static int next_state(walleye *we, cv_frame_state *fs, uint64_t *hash) {
  double stop_since = 0;
  for (;;) {
    const uint8_t *data;
    long len;
    while ((len = cv_mailbox_take(we->state_mb, &data, NULL)) >= 0) {
      cv_err err;
      cv_frame_state t;
      if (cv_frame_state_unpack(data, (size_t)len, &t, &err)) {
        fprintf(stderr, "cave run: rank %d: %s (state dropped)\n", we->s->rank, err.msg);
        continue;
      }
      *fs = t;
      if (hash) *hash = cv_hash64(data, (size_t)len);
      return !(t.flags & CV_FS_QUIT); /* one frame at a time: later states stay queued */
    }
    if (we->ping_mb) idle(we);
    else cv_comm_progress();
    if (cv_comm_declared_dead()) return 0; /* stalled, not dead: no quit will come */
    watch_signal(we);
    if (*we->s->stop) {
      if (stop_since == 0) stop_since = cv_service_now();
      else if (cv_service_now() - stop_since > 5) return 0;
    }
    nap();
  }
}

/* ---- phases of a frame ----------------------------------------------------- */

static void idle_cb(void *we) { idle(we); }

/* Triangles this output's views draw from the config's head: its frame's
 * relative cost (the cheapest wall-eye of a host leads the shared lighting). */
static size_t view_cost(const walleye *we) {
  const cv_service *s = we->s;
  const cv_wall *W = &s->cave.walls[we->wall];
  double eyes[2][3];
  cv_head_eyes(s->cave.head, s->cave.gaze, s->cave.eye_separation, eyes[0], eyes[1]);
  size_t n = 0;
  for (int k = 0; k < we->n_eyes; k++) {
    cv_render_view rv;
    memset(&rv, 0, sizeof rv);
    if (cv_offaxis_compute(W->pa, W->pb, W->pc, eyes[we->ev[k].eye], s->cave.near, s->cave.far, &rv.proj)) continue;
    memcpy(rv.scene_offset, s->cave.scene_offset, sizeof rv.scene_offset);
    rv.w = we->w, rv.h = we->h, rv.supersample = 1;
    n += cv_renderer_view_triangles(we->r, &rv);
  }
  return n;
}

/* A new light key: the lighting computed, or taken from the host's leader
 * (lightshare.h); what was done goes to the master (CV_TAG_LIGHT). */
static void relight_if_needed(walleye *we, const cv_frame_state *fs, cv_frame_timing *tm) {
  cv_err err;
  if (we->have_light && fs->light_key == we->light_key) {
    /* a prefetch the state did not confirm: back to the current lighting */
    if (cv_lightshare_pending(&we->ls) && cv_lightshare_restore(&we->ls, we->r, &err)) {
      fprintf(stderr, "cave run: rank %d: lighting: %s\n", we->s->rank, err.msg);
      we->have_light = 0;
    } else {
      return;
    }
  }
  cv_lighting l;
  memset(&l, 0, sizeof l);
  l.bands = fs->bands;
  memcpy(l.sh, fs->sh, sizeof l.sh);
  l.has_sun = fs->has_sun;
  memcpy(l.sun_dir, fs->sun_dir, sizeof l.sun_dir);
  memcpy(l.sun_E, fs->sun_E, sizeof l.sun_E);
  cv_light_msg msg;
  if (cv_lightshare_relight(&we->ls, we->s, we->r, we->mix, &l, &fs->drive, fs->light_key, tm, idle_cb, we,
                            &msg, &err)) {
    fprintf(stderr, "cave run: rank %d: lighting: %s\n", we->s->rank, err.msg);
  } else {
    we->light_key = fs->light_key;
    we->have_light = 1;
  }
  msg.frame = fs->frame;
  cv_comm_send(&msg, sizeof msg, 0, CV_TAG_LIGHT);
}

/* Renders one eye and fills its report's statistics and stage times. */
static void render_eye(walleye *we, eye_view *v, const cv_frame_state *fs, cv_frame_timing *tm,
                       cv_walleye_report *rep) {
  cv_service *s = we->s;
  const cv_wall *W = &s->cave.walls[we->wall];
  double eyes[2][3];
  if (fs->has_eyes)
    memcpy(eyes, fs->eyes, sizeof eyes); /* a calibrated tracker: IPD and roll */
  else
    cv_head_eyes(fs->head, fs->gaze, s->cave.eye_separation, eyes[0], eyes[1]);
  cv_render_view rv;
  memset(&rv, 0, sizeof rv);
  const int vst = cv_offaxis_compute(W->pa, W->pb, W->pc, eyes[v->eye], s->cave.near, s->cave.far, &rv.proj);
  memcpy(rv.scene_offset, s->cave.scene_offset, sizeof rv.scene_offset);
  rv.w = we->w;
  rv.h = we->h;
  rv.supersample = s->cave.supersample;
  cv_drago d;
  cv_drago_default(&d);
  d.bias = s->cave.drago_bias;
  d.ldmax = s->cave.drago_ldmax;
  d.lwa = fs->lwa;
  d.lwmax = fs->lwmax;
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  cv_err err;
  /* No luminance pass: the adaptation statistics of this frame (which the
   * master uses for the next one) come from its own HDR image, reduced on
   * the GPU to the luminance image (lum_res^2) and Drago's Lwmax (the
   * largest luminance of all its pixels).  The HDR image itself is read
   * back only on the frames that write it. */
  double mx = 0;
  uint64_t bad = 0;
  cv_image *hdr = (fs->flags & CV_FS_WRITE) ? v->hdr : NULL;
  const double c0 = thread_cpu_ms();
  int st = vst;
  if (!st && we->gpu_post) {
    /* the display image stays on the GPU; it comes back only for files and previews */
    st = cv_renderer_shade_gpu(we->r, &rv, &dc, hdr, v->lum, &mx, &bad, tm, &err);
    if (!st && (fs->flags & (CV_FS_WRITE | CV_FS_PREVIEW))) st = cv_renderer_display_read(we->r, v->disp_img, &err);
  } else if (!st) {
    st = cv_renderer_shade_stats(we->r, &rv, &dc, 0, v->disp_img, hdr, v->lum, &mx, &bad, tm, &err);
  }
  we->cpu_gl += thread_cpu_ms() - c0;
  v->failed = st != 0;
  if (st) {
    /* head behind this wall or a GL failure: black frame, no statistics */
    if (!vst) fprintf(stderr, "cave run: rank %d: frame %u: %s\n", s->rank, fs->frame, err.msg);
    memset(v->disp_img->px, 0, 3 * (size_t)we->w * we->h * sizeof(float));
    memset(v->hdr->px, 0, 3 * (size_t)we->w * we->h * sizeof(float));
  } else {
    /* Foveal statistics from the head position (the cone of the gaze). */
    const double half_angle = 0.5 * s->cave.foveal_deg * M_PI / 180.0;
    cv_lumstats ls;
    memset(&ls, 0, sizeof ls);
    if (cv_foveal_touches(W->pa, W->pb, W->pc, fs->head, fs->gaze, half_angle))
      cv_foveal_accumulate(v->lum->px, v->lum->w, v->lum->h, W->pa, W->pb, W->pc, fs->head, fs->gaze,
                           half_angle, &ls);
    rep->sum_log = ls.sum_log;
    rep->weight = ls.weight;
    rep->n_pixels = ls.n_pixels;
    /* the HDR pixels left out of the luminance image and Lwmax (a luminance
     * pixel the foveal sum skips, ls.n_invalid, is made of such pixels only) */
    rep->n_invalid = bad;
    rep->max_l = mx;
  }
  rep->ms_lum = tm->lum_ms + tm->lum_read_ms;
  rep->ms_depth = tm->depth_ms;
  rep->ms_shade = tm->shade_ms + tm->background_ms + tm->resolve_ms;
  rep->ms_read = tm->read_ms;
}

/* Sends one eye's report (+ the patch means of its image) to the master. */
static void send_report(walleye *we, eye_view *v, cv_walleye_report *rep) {
  size_t np = 0;
  if (we->disp) {
    np = (size_t)we->S->nu * we->S->nv;
    cv_err err;
    const double c0 = thread_cpu_ms();
    if (v->failed) memset(v->patch, 0, 3 * np * sizeof *v->patch);
    else if (!we->gpu_post)
      cv_downsample_to_patches(v->disp_img, we->S->nu, we->S->nv, we->S->edge_u, we->S->edge_v, v->patch);
    else if (cv_renderer_patch_means(we->r, v->patch, &err)) {
      fprintf(stderr, "cave run: rank %d: frame %u: %s\n", we->s->rank, rep->frame, err.msg);
      memset(v->patch, 0, 3 * np * sizeof *v->patch);
    }
    if (we->gpu_post) we->cpu_gl += thread_cpu_ms() - c0;
  }
  uint64_t io_read, io_up;
  cv_renderer_io(we->r, &io_read, &io_up);
  rep->bytes_read = io_read - we->io_read_rep;
  rep->bytes_up = io_up - we->io_up_rep;
  we->io_read_rep = io_read, we->io_up_rep = io_up;
  rep->ms_cpu = we->prev_cpu;
  rep->ms_gpu = we->prev_gpu;
  rep->ms_corr_wait = we->prev_wait;
  rep->corr_frame = we->prev_corr;
  rep->late_corr = we->late_corr;
  cv_filewriter_stats fst;
  cv_filewriter_stats_get(we->fw, &fst);
  rep->files_dropped = fst.dropped + we->files_nomem;
  rep->files_failed = fst.failed;
  if (fst.failed && !we->files_said) { /* at once, once: the master stops the run (master_out.c) */
    we->files_said = 1;
    fprintf(stderr, "cave run: rank %d: files not written: %s\n", we->s->rank, fst.first_error);
  }
  rep->ms_lcd = we->lcd_ms;
  rep->lcd_rounds_done = we->lcd_rounds_done;
  rep->swap_frame = we->swap_frame;
  rep->swap_t = we->swap_t;
  rep->ms_present = we->ms_present;
  rep->ms_barrier = we->ms_barrier;
  size_t len = CV_WALLEYE_REPORT_BYTES + (we->disp ? sizeof(cv_patch_msg) + 3 * np * sizeof(float) : 0);
  uint8_t *buf = malloc(len);
  if (buf && cv_walleye_report_pack(rep, buf) == CV_OK) {
    if (we->disp) {
      cv_patch_msg pm = {.frame = rep->frame, .n = (uint32_t)np};
      memcpy(buf + CV_WALLEYE_REPORT_BYTES, &pm, sizeof pm);
      float *px = (float *)(void *)(buf + CV_WALLEYE_REPORT_BYTES + sizeof pm);
      for (size_t i = 0; i < 3 * np; i++) px[i] = (float)v->patch[i];
    }
    cv_comm_send(buf, len, 0, CV_TAG_REPORT);
  }
  free(buf);
}

/* Desktop preview (frames the master marks CV_FS_PREVIEW, left eye, walls
 * the preview shows): the uncompensated tone-mapped image as 8-bit codes.
 * Uncompensated because a desktop monitor does not scatter light between
 * walls: the target image is what a viewer in the CAVE should see. */
static void send_preview(walleye *we, const eye_view *v, const cv_frame_state *fs) {
  const cv_service *s = we->s;
  if (!(fs->flags & CV_FS_PREVIEW) || v->eye != 0 || !(s->o.present & CV_PRESENT_DESKTOP)) return;
  if (s->o.desktop_view >= 0 && s->o.desktop_view != we->wall) return;
  const size_t npx = 3 * (size_t)we->w * we->h;
  cv_preview_msg h = {.frame = fs->frame, .wall = we->wall, .w = we->w, .h = we->h};
  uint8_t *buf = malloc(sizeof h + npx);
  if (!buf) return; /* the master shows the next preview frame */
  memcpy(buf, &h, sizeof h);
  cv_rec709_codes(&we->lut, v->disp_img->px, npx, buf + sizeof h);
  cv_comm_send(buf, sizeof h + npx, 0, CV_TAG_PREVIEW);
  free(buf);
}

/* Keeps a correction message if it is frame `want`'s (into delta: got),
 * of a later frame (kept for that frame) or the newest older one so far
 * (delta, used if want's does not come). */
static int keep_correction(walleye *we, const uint8_t *data, long l, uint32_t want) {
  const size_t np = (size_t)we->S->nu * we->S->nv;
  cv_patch_msg pm;
  if ((size_t)l != sizeof pm + 3 * np * sizeof(float)) return 0;
  memcpy(&pm, data, sizeof pm);
  if (pm.n != np) return 0;
  if (pm.frame > want && (we->pend_frame == 0xffffffffu || pm.frame > we->pend_frame)) {
    memcpy(we->pend, data + sizeof pm, 3 * np * sizeof(float));
    we->pend_frame = pm.frame;
    return 0;
  }
  if (pm.frame > want || (we->have_delta && we->corr_frame != 0xffffffffu && pm.frame < we->corr_frame)) return 0;
  memcpy(we->delta, data + sizeof pm, 3 * np * sizeof(float));
  we->have_delta = 1;
  we->corr_frame = pm.frame;
  return pm.frame == want;
}

/* Frame `want`'s correction for the wall (want = this frame - lag), waited
 * for at most --timeout-ms / 2 (the start-up time on frame 0); when it does not
 * come, the last one stays and it counts as late.  Exactly frame want's is
 * applied whenever it comes in time, so the images do not depend on timing.
 * Returns the ms waited. */
static double take_correction(walleye *we, const cv_frame_state *fs, int64_t want) {
  cv_service *s = we->s;
  if (want < 0) return 0; /* lag 1 on frame 0: nothing solved yet */
  const double t0 = cv_service_now(), c0 = thread_cpu_ms();
  /* half the master's deadline: the next frame's report must still make it */
  const double deadline = t0 + (fs->frame == 0 ? fmax(s->o.timeout_ms * 1e-3, s->o.startup_timeout_s)
                                                : 0.5e-3 * s->o.timeout_ms);
  const size_t np = (size_t)we->S->nu * we->S->nv;
  int got = we->have_delta && we->corr_frame == (uint32_t)want;
  if (!got && we->pend_frame == (uint32_t)want) { /* it came during an earlier frame */
    memcpy(we->delta, we->pend, 3 * np * sizeof(float));
    we->have_delta = 1, we->corr_frame = (uint32_t)want, we->pend_frame = 0xffffffffu;
    got = 1;
  }
  while (!got) {
    const uint8_t *data;
    long l;
    while (!got && (l = cv_mailbox_take(we->corr_mb, &data, NULL)) >= 0) got = keep_correction(we, data, l, (uint32_t)want);
    /* the stop flag ends the wait only on frame 0 (start-up time): later a
     * signal to this rank alone must not put it a frame ahead of the others
     * (the wait is bounded by the deadline; the master's quit follows) */
    if (got || cv_service_now() > deadline || (*s->stop && fs->frame == 0)) break;
    idle(we);
    nap();
  }
  if (!got) we->late_corr++;
  we->cpu_skip += thread_cpu_ms() - c0;
  return (cv_service_now() - t0) * 1e3;
}

/* out = the projector image of each eye on the CPU (--post cpu, and the
 * files of a written frame): compensated (equation 7) or as rendered;
 * codes: its 8-bit codes too. */
static void compensate_eyes(walleye *we, int codes) {
  const size_t px = 3 * (size_t)we->w * we->h;
  double *dd = NULL;
  if (we->disp && we->have_delta) {
    const size_t np = (size_t)we->S->nu * we->S->nv;
    dd = malloc(3 * np * sizeof *dd);
    if (dd)
      for (size_t i = 0; i < 3 * np; i++) dd[i] = we->delta[i];
  }
  for (int k = 0; k < we->n_eyes; k++) {
    eye_view *v = &we->ev[k];
    if (dd)
      cv_apply_patch_delta(v->disp_img, dd, we->S->nu, we->S->nv, we->S->edge_u, we->S->edge_v, v->out);
    else
      memcpy(v->out->px, v->disp_img->px, px * sizeof(float));
    if (codes) cv_rec709_codes(&we->lut, v->out->px, px, v->code);
  }
  free(dd);
}

/* The GPU post pass of eye k (--post gpu): equation 7 with the correction
 * in hand (none without compensation or before the first), into its slot;
 * kept: from the display image kept for it (cv_renderer_display_keep). */
static void post_eye(walleye *we, eye_view *v, int kept) {
  cv_err err;
  const double c0 = thread_cpu_ms();
  const float *delta = we->disp && we->have_delta ? we->delta : NULL;
  if (v->failed ? cv_renderer_post_black(we->r, v->slot, &err) : cv_renderer_post(we->r, v->slot, kept, delta, &err))
    fprintf(stderr, "cave run: rank %d: %s\n", we->s->rank, err.msg);
  we->cpu_gl += thread_cpu_ms() - c0;
}

/* Scheduled swap: ready to the master, then its swap time (this rank's
 * clock) for this frame, slept to. */
static void wait_for_go(walleye *we, uint32_t frame) {
  const double ready = (double)frame;
  cv_comm_send(&ready, sizeof ready, 0, CV_TAG_SWAPREADY);
  for (;;) {
    const uint8_t *data;
    long len;
    while ((len = cv_mailbox_take(we->go_mb, &data, NULL)) >= 0) {
      double msg[2];
      if (len != sizeof msg) continue;
      memcpy(msg, data, sizeof msg);
      if ((uint32_t)msg[0] != frame) continue; /* an older frame's */
      const double at = msg[1];
      struct timespec ts = {(time_t)floor(at), (long)((at - floor(at)) * 1e9)};
      if (at > cv_service_now()) clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
      return;
    }
    if (*we->s->stop) return;
    answer_pings(we);
    watch_window(we);
    cv_comm_progress();
    sched_yield();
  }
}

/* Present: draw, glFinish, meet every render rank at the barrier, swap,
 * stamp the swap's return.  Without a window only the barrier (when the
 * swap lock is on), so the frame loop keeps the same shape. */
static void present(walleye *we, const cv_frame_state *fs) {
  cv_service *s = we->s;
  const double t0 = cv_service_now();
  cv_err err;
  const int window = (s->o.present & CV_PRESENT_WINDOW) && we->win_event == CV_WIN_OK;
  const double c0 = thread_cpu_ms();
  if (window) {
    const int packed = we->o->eyes == 3;
    const int st = we->gpu_post ? cv_renderer_present_slots(we->r, we->o->stereo, &err)
                                : cv_renderer_present(we->r, we->ev[0].code, packed ? we->ev[1].code : NULL, we->w,
                                                      we->h, we->o->stereo, &err);
    if (st) fprintf(stderr, "cave run: rank %d: frame %u: %s\n", s->rank, fs->frame, err.msg);
  }
  we->cpu_drawn = thread_cpu_ms();
  we->cpu_gl += we->cpu_drawn - c0;
  double tb = cv_service_now();
  if (s->o.swap_lock && s->o.swap_sync == CV_SWAP_SCHEDULED) {
    wait_for_go(we, fs->frame);
  } else if (s->o.swap_lock) {
    cv_comm_render_barrier_start();
    /* Poll, yielding the core: on an oversubscribed host the ranks that
     * still render (and MPI's progress) need it, and a rank that spun here
     * would see the barrier's release a scheduler slice late. */
    while (!cv_comm_render_barrier_test()) {
      answer_pings(we);
      cv_comm_progress();
      sched_yield();
    }
  }
  const double tb1 = cv_service_now();
  if (window && we->win_event == CV_WIN_OK && cv_renderer_swap(we->r, &err)) {
    watch_window(we);
    if (!we->win_event) fprintf(stderr, "cave run: rank %d: %s\n", s->rank, err.msg);
  }
  we->swap_t = cv_service_now();
  we->swap_frame = fs->frame;
  we->ms_barrier = (tb1 - tb) * 1e3;
  we->ms_present = (we->swap_t - t0) * 1e3;
}

/* A written frame on the GPU path: each eye's codes (what the window
 * shows) and, on the CPU, the compensated display-linear image the master's
 * viewer simulation takes. */
static void fetch_written(walleye *we) {
  cv_err err;
  for (int k = 0; k < we->n_eyes; k++)
    if (cv_renderer_post_read(we->r, we->ev[k].slot, we->ev[k].code, &err))
      fprintf(stderr, "cave run: rank %d: %s\n", we->s->rank, err.msg);
  compensate_eyes(we, 0);
}

/* One eye's files of a written frame, written by the rank's writer thread
 * (io/filewriter.h) from copies: the linear HDR EXR, the projector's 8-bit
 * codes (the same bytes the window shows) and, with compensation, the
 * uncompensated tone-mapped image beside them (encoded in the thread). */
typedef struct eye_files {
  char exr[CV_PATHLEN + 96], png[CV_PATHLEN + 96], unc[CV_PATHLEN + 96];
  cv_image *hdr, *disp;       /* disp NULL: no uncompensated image */
  uint8_t *code;
  const cv_rec709_lut *lut;
} eye_files;

static void eye_files_free(void *p) {
  eye_files *f = p;
  cv_image_destroy(f->hdr);
  cv_image_destroy(f->disp);
  free(f->code);
  free(f);
}

static int eye_files_write(void *p, cv_err *err) {
  eye_files *f = p;
  const int w = f->hdr->w, h = f->hdr->h;
  int st = cv_exr_write(f->exr, f->hdr, 1, CV_EXR_ZIP, err);
  if (!st) st = cv_write_png_atomic(f->png, w, h, 3, f->code, err);
  if (!st && f->disp) {
    cv_rec709_codes(f->lut, f->disp->px, 3 * (size_t)w * h, f->code); /* the codes are written already */
    st = cv_write_png_atomic(f->unc, w, h, 3, f->code, err);
  }
  return st;
}

static cv_image *image_copy(const cv_image *a) {
  cv_image *b = NULL;
  if (cv_image_create(a->w, a->h, a->c, &b)) return NULL;
  memcpy(b->px, a->px, (size_t)a->w * a->h * a->c * sizeof(float));
  return b;
}

/* --present files: one eye's files to the writer thread (copies; a full
 * queue drops them, counted).  Nothing here waits for the disk. */
static void queue_files(walleye *we, const eye_view *v, const cv_frame_state *fs) {
  if (!we->fw) return;
  const char *wn = we->s->cave.walls[we->wall].name, *en = v->eye ? "R" : "L", *dir = we->s->o.out_dir;
  eye_files *f = calloc(1, sizeof *f);
  if (!f) return;
  snprintf(f->exr, sizeof f->exr, "%s/frame%05u_%s_%s.exr", dir, fs->frame, wn, en);
  snprintf(f->png, sizeof f->png, "%s/frame%05u_%s_%s.png", dir, fs->frame, wn, en);
  snprintf(f->unc, sizeof f->unc, "%s/frame%05u_%s_%s_uncompensated.png", dir, fs->frame, wn, en);
  const size_t n = 3 * (size_t)we->w * we->h;
  f->hdr = image_copy(v->hdr);
  f->disp = we->disp ? image_copy(v->disp_img) : NULL;
  f->code = malloc(n);
  f->lut = &we->lut;
  if (!f->hdr || (we->disp && !f->disp) || !f->code) {
    eye_files_free(f);
    we->files_nomem++;
    return;
  }
  memcpy(f->code, v->code, n);
  cv_filewriter_submit(we->fw, (cv_write_job){eye_files_write, eye_files_free, f});
}

/* The left eye of a written frame: its display-linear images, compensated
 * and not, to the master (montages and the viewer simulation). */
static void send_images(walleye *we, const eye_view *v, const cv_frame_state *fs) {
  if (v->eye != 0) return;
  const size_t npx = 3 * (size_t)we->w * we->h;
  size_t n = sizeof(cv_patch_msg) + 2 * sizeof(int32_t) + 2 * npx * sizeof(float);
  uint8_t *buf = malloc(n);
  if (!buf) return;
  cv_patch_msg pm = {.frame = fs->frame, .n = (uint32_t)we->wall};
  int32_t wh[2] = {we->w, we->h};
  memcpy(buf, &pm, sizeof pm);
  memcpy(buf + sizeof pm, wh, sizeof wh);
  memcpy(buf + sizeof pm + sizeof wh, v->out->px, npx * sizeof(float));
  memcpy(buf + sizeof pm + sizeof wh + npx * sizeof(float), v->disp_img->px, npx * sizeof(float));
  cv_comm_send(buf, n, 0, CV_TAG_IMAGE);
  free(buf);
}

/* The ready line's text: where this rank renders and with what. */
static void ready_text(const walleye *we, char *buf, size_t cap) {
  char host[128];
  cv_comm_host(host, sizeof host);
  const cv_output *o = we->o;
  const int win = (we->s->o.present & CV_PRESENT_WINDOW) != 0;
  int ww = 0, wh = 0;
  cv_renderer_window_size(we->r, &ww, &wh);
  char where[160];
  if (win) snprintf(where, sizeof where, "window %dx%d+%d+%d on %s", ww, wh, we->spec.x, we->spec.y,
                    cv_renderer_platform(we->r));
  else snprintf(where, sizeof where, "headless on the %s", cv_renderer_platform(we->r));
  char share[160];
  cv_lightshare_describe(&we->ls, share, sizeof share);
  cv_shadow_casters sc;
  cv_renderer_shadow_casters(we->r, &sc);
  char casters[64];
  if (sc.tolerance_m > 0) snprintf(casters, sizeof casters, "casters within %.2g mm", 1e3 * sc.tolerance_m);
  else snprintf(casters, sizeof casters, "the mesh");
  char post[sizeof we->post_why + 64];
  if (we->gpu_post) snprintf(post, sizeof post, "frame end on the GPU (patch means, equation 7, Rec.709 codes in shaders; "
                             "only patch means and luminance statistics read back)");
  else snprintf(post, sizeof post, "frame end on the CPU (image read back: %s)", we->post_why);
  snprintf(buf, cap, "rank %d on %s: wall %s, %s; %s; GL %s (%s); relight %s from %s transfer; luminance statistics %s; %s; sun's shadow map of %s; hardware swap sync: none (EGL has no swap-group extension); shared lighting: %s",
           we->s->rank, host, we->s->cave.walls[we->wall].name,
           o->eyes == 3 ? cv_stereo_mode_name(o->stereo) : (o->eyes == 1 ? "left eye" : "right eye"), where,
           cv_renderer_gl_name(we->r), cv_renderer_is_software(we->r) ? "software" : "hardware GPU",
           cv_renderer_relight_on_cpu(we->r) ? "on the CPU" : "by transform feedback",
           cv_renderer_half_transfer(we->r) ? "half-float" : "float",
           we->gpu_post || cv_renderer_lum_stats_on_gpu(we->r) ? "on the GPU" : "on the CPU", post, casters, share);
}

/* The master's adaptation priming (CV_FS_MEASURE): every eye rendered and
 * reported (its foveal statistics), nothing presented, written or sent to
 * the LCD worker. */
static void measure_frame(walleye *we, const cv_frame_state *fs, uint64_t state_hash, double t0) {
  cv_frame_timing tm;
  memset(&tm, 0, sizeof tm);
  relight_if_needed(we, fs, &tm);
  for (int k = 0; k < we->n_eyes; k++) {
    cv_walleye_report rep;
    memset(&rep, 0, sizeof rep);
    rep.frame = fs->frame;
    rep.rank = we->s->rank;
    rep.wall = we->wall;
    rep.eye = we->ev[k].eye;
    rep.state_hash = state_hash;
    render_eye(we, &we->ev[k], fs, &tm, &rep);
    rep.ms_total = (cv_service_now() - t0) * 1e3;
    send_report(we, &we->ev[k], &rep);
  }
}

/* Each eye: render, report, and on the GPU path its post pass as soon as
 * its correction is in hand (frame N - lag's; with lag 0 after every eye
 * reported, the first eye's display image kept meanwhile). */
static void render_eyes(walleye *we, const cv_frame_state *fs, uint64_t state_hash, double t0,
                        cv_frame_timing *tm, double *wait) {
  const int lag = we->s->o.compensation_lag;
  /* frame N - lag's correction; frame 0 waits for its own (the first frames are
   * compensated too: the master solves frame 0 while it waits for frame 1) */
  const int64_t want = fs->frame == 0 ? 0 : (int64_t)fs->frame - lag;
  for (int k = 0; k < we->n_eyes; k++) {
    eye_view *v = &we->ev[k];
    cv_walleye_report rep;
    memset(&rep, 0, sizeof rep);
    rep.frame = fs->frame;
    rep.rank = we->s->rank;
    rep.wall = we->wall;
    rep.eye = v->eye;
    rep.state_hash = state_hash;
    render_eye(we, v, fs, tm, &rep);
    rep.ms_total = (cv_service_now() - t0) * 1e3;
    send_preview(we, v, fs); /* before the report: complete when the frame is */
    send_report(we, v, &rep);
    if (!we->gpu_post) continue;
    if (we->disp && lag > 0 && k == 0) *wait += take_correction(we, fs, want);
    if (!we->disp || lag > 0) {
      post_eye(we, v, 0);
    } else if (k + 1 < we->n_eyes) {
      cv_err err;
      const double c0 = thread_cpu_ms();
      if (cv_renderer_display_keep(we->r, v->slot, &err)) fprintf(stderr, "cave run: rank %d: %s\n", we->s->rank, err.msg);
      we->cpu_gl += thread_cpu_ms() - c0;
    }
  }
  if (we->disp && (lag == 0 || !we->gpu_post)) *wait += take_correction(we, fs, want);
  if (we->gpu_post && we->disp && lag == 0)
    for (int k = 0; k < we->n_eyes; k++) post_eye(we, &we->ev[k], k + 1 < we->n_eyes);
}

/* One frame: relight, the eyes, the correction, present, files (written by
 * the writer thread: failures counted, said at the end); the frame path's
 * figures kept for the next report. */
static void run_frame(walleye *we, const cv_frame_state *fs, uint64_t state_hash, double t0) {
  const double c0 = thread_cpu_ms();
  we->cpu_gl = we->cpu_skip = 0;
  if (we->lw) cv_lcd_worker_post(we->lw, fs);
  cv_frame_timing tm;
  memset(&tm, 0, sizeof tm);
  relight_if_needed(we, fs, &tm);
  we->cpu_skip += thread_cpu_ms() - c0; /* a lighting change is not the frame's path */
  double wait = 0;
  if (we->gpu_post) cv_renderer_gpu_timer_begin(we->r);
  render_eyes(we, fs, state_hash, t0, &tm, &wait);
  if (we->gpu_post) cv_renderer_gpu_timer_end(we->r);
  else compensate_eyes(we, 1);
  present(we, fs);
  we->prev_cpu = fmax(0, we->cpu_drawn - c0 - we->cpu_gl - we->cpu_skip);
  const double gpu = we->gpu_post ? cv_renderer_gpu_timer_result(we->r) : NAN;
  we->prev_gpu = isfinite(gpu) ? gpu : -1;
  we->prev_wait = wait;
  we->prev_corr = we->have_delta ? we->corr_frame : 0xffffffffu;
  if (fs->flags & CV_FS_WRITE) { /* files (when asked) and the master's viewer simulation */
    if (we->gpu_post) fetch_written(we);
    for (int k = 0; k < we->n_eyes; k++) {
      queue_files(we, &we->ev[k], fs);
      send_images(we, &we->ev[k], fs);
    }
  }
}

/* The writer's queue written out, its thread ended; a file that could not
 * be written or a written frame dropped is said once.  1 when files failed. */
static int finish_files(walleye *we) {
  if (!we->fw) return 0;
  cv_filewriter *w = we->fw;
  we->fw = NULL;
  cv_filewriter_stats st;
  cv_filewriter_drain(w, &st);
  cv_filewriter_destroy(w);
  if (st.dropped + we->files_nomem)
    fprintf(stderr, "cave run: rank %d: %llu written frames' files dropped (the writer's queue was full)\n",
            we->s->rank, (unsigned long long)(st.dropped + we->files_nomem));
  if (st.failed)
    fprintf(stderr, "cave run: rank %d: %llu frames' files not written; first: %s\n", we->s->rank,
            (unsigned long long)st.failed, st.first_error);
  return st.failed > 0;
}

int cv_walleye_run(cv_service *s) {
  walleye WE;
  memset(&WE, 0, sizeof WE);
  walleye *we = &WE;
  we->s = s;
  cv_err err;
  cv_err_clear(&err);
  int st = walleye_setup(we, &err);
  /* collective over the render ranks, also after a failed set-up (no part) */
  if (cv_lightshare_setup(&we->ls, s, st == CV_OK ? we->r : NULL, st == CV_OK ? view_cost(we) : 0, 512, 256))
    fprintf(stderr, "cave run: rank %d: shared lighting: MPI shared memory failed, computing the lighting\n", s->rank);
  {
    char msg[1400];
    if (st == CV_OK) ready_text(we, msg, sizeof msg);
    else snprintf(msg, sizeof msg, "rank %d (outputs[%d], wall %s): %s", s->rank, s->rank - 1,
                  we->o ? s->cave.walls[we->wall].name : "?", err.msg);
    cv_service_ready(st == CV_OK, we->prt ? we->prt->meta.file_hash : 0, msg);
  }
  if (st) {
    /* wait for the master's quit so the job ends cleanly */
    cv_frame_state fs;
    if (we->state_mb) while (next_state(we, &fs, NULL)) {}
    walleye_free(we);
    cv_comm_flush(2);
    return 1;
  }
  cv_frame_state fs;
  int rc = 0;
  uint64_t state_hash = 0;
  while (next_state(we, &fs, &state_hash)) {
    const double t0 = cv_service_now();
    if (fs.flags & CV_FS_MEASURE) { /* adaptation priming: luminance reports only */
      measure_frame(we, &fs, state_hash, t0);
      continue;
    }
    run_frame(we, &fs, state_hash, t0);
    /* the host's leader: the next frame's lighting while the others render */
    if (we->have_light) cv_lightshare_prefetch(&we->ls, s, we->r, we->mix, &fs, we->light_key);
    idle(we);
  }
  if (we->lw) cv_lcd_worker_send_ready(we->lw, send_to_master, NULL, NULL, NULL);
  rc |= finish_files(we);
  cv_comm_flush(5);
  walleye_free(we);
  return rc;
}
