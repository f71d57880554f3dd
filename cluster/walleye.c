/* Wall-eye ranks: rank 1 + 2w + e renders wall w for eye e (0 left, 1 right).
 * Per frame: take the master's frame state; relight when the light key
 * changed; the three-pass frame (luminance at lum_res for the foveal
 * statistics, depth, PRT shading tone-mapped with the shared adaptation,
 * display-linear); the patch means of the display image go to the master
 * with the report; the master's correction for this wall (or the last one,
 * when it is late) is applied with equation 7; images are written on the
 * frames the master marks.  An idle thread renders LCD rounds meanwhile. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "compensate/resample.h"
#include "core/hash.h"
#include "io/exr.h"
#include "lcd/gather.h"
#include "lcdwork.h"
#include "render/renderer.h"
#include "service_internal.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"
#include "view/offaxis.h"

static int send_to_master(const uint8_t *buf, size_t len, void *user) {
  (void)user;
  return cv_comm_send(buf, len, 0, CV_TAG_LCD);
}

typedef struct walleye {
  cv_service *s;
  int wall, eye;
  cv_prt *prt;
  cv_renderer *r;
  cv_lcd_worker *lw;
  cv_display *disp;
  const cv_display_surface *S;
  int w, h;
  cv_image *disp_img, *hdr, *lum, *out;
  double *patch;      /* 3 np */
  float *delta;       /* 3 np: last correction */
  int have_delta;
  uint64_t light_key;
  int have_light;
  cv_mailbox *state_mb, *corr_mb, *lcdimg_mb;
  uint64_t lcd_rounds_done;
  double lcd_ms;
  uint64_t late_corr;
  int have_panel;
  cv_lcd_panel panel;
  cv_lightmix *mix;
} walleye;

static void walleye_free(walleye *we) {
  cv_lcd_worker_destroy(we->lw);
  cv_lightmix_destroy(we->mix);
  cv_renderer_destroy(we->r);
  cv_prt_destroy(we->prt);
  cv_display_destroy(we->disp);
  cv_image_destroy(we->disp_img);
  cv_image_destroy(we->hdr);
  cv_image_destroy(we->lum);
  cv_image_destroy(we->out);
  free(we->patch);
  free(we->delta);
  cv_mailbox_close(we->state_mb);
  cv_mailbox_close(we->corr_mb);
  cv_mailbox_close(we->lcdimg_mb);
}

static int walleye_setup(walleye *we, cv_err *err) {
  cv_service *s = we->s;
  const cv_wall *W = &s->cave.walls[we->wall];
  we->w = s->o.size > 0 ? s->o.size : W->res[0];
  we->h = s->o.size > 0 ? s->o.size : W->res[1];
  int st = cv_prt_read(s->o.scene_path, &we->prt, err);
  if (st) return st;
  cv_render_opts ro;
  cv_render_default_opts(&ro);
  ro.timing = 1;
  st = cv_renderer_create(we->prt, &ro, &we->r, err);
  if (st) return st;
  st = cv_service_lightmix(s, (int)we->prt->bands, &we->mix, err);
  if (st) return st;
  if (cv_image_create(we->w, we->h, 3, &we->disp_img) || cv_image_create(we->w, we->h, 3, &we->hdr) ||
      cv_image_create(we->w, we->h, 3, &we->out) ||
      cv_image_create(s->cave.lum_res, s->cave.lum_res, 1, &we->lum))
    return cv_err_set(err, CV_ERR_NOMEM, "wall-eye: out of memory");
  if (s->o.compensate) {
    st = cv_service_display(s, &we->disp, err);
    if (st) return st;
    we->S = cv_display_surface_at(we->disp, (size_t)we->wall);
    const size_t np = (size_t)we->S->nu * we->S->nv;
    we->patch = calloc(3 * np, sizeof *we->patch);
    we->delta = calloc(3 * np, sizeof *we->delta);
    if (!we->patch || !we->delta) return cv_err_set(err, CV_ERR_NOMEM, "wall-eye: out of memory");
    we->corr_mb = cv_mailbox_open(0, CV_TAG_CORR, sizeof(cv_patch_msg) + 3 * np * sizeof(float));
    if (!we->corr_mb) return cv_err_set(err, CV_ERR_NOMEM, "wall-eye: cannot post receives");
  }
  if (s->o.lcd) {
    /* The panel frame, to show the LCD image on it. */
    cv_mesh *mesh;
    if (cv_prt_to_mesh(we->prt, &mesh) == CV_OK) {
      we->have_panel = cv_lcd_panel_from_mesh(mesh, &we->panel, NULL) == CV_OK;
      cv_mesh_destroy(mesh);
    }
  }
  const int index = cv_service_contributor(s, s->rank);
  if (index >= 0) {
    st = cv_lcd_worker_create(s, we->prt, index, &we->lw, err);
    if (st) return st;
  }
  we->state_mb = cv_mailbox_open(0, CV_TAG_STATE, CV_FRAME_STATE_BYTES);
  we->lcdimg_mb = cv_mailbox_open(0, CV_TAG_LCDIMG,
                                  sizeof(cv_lcdimg_msg) + 3 * (size_t)s->o.lcd_w * s->o.lcd_h * sizeof(float));
  if (!we->state_mb || !we->lcdimg_mb) return cv_err_set(err, CV_ERR_NOMEM, "wall-eye: cannot post receives");
  return CV_OK;
}

/* Background work while waiting: LCD rounds out, LCD images in. */
static void idle(walleye *we) {
  if (we->lw) cv_lcd_worker_send_ready(we->lw, send_to_master, NULL, &we->lcd_rounds_done, &we->lcd_ms);
  const uint8_t *data;
  long len;
  while ((len = cv_mailbox_take(we->lcdimg_mb, &data, NULL)) >= 0) {
    cv_lcdimg_msg h;
    if ((size_t)len < sizeof h) continue;
    memcpy(&h, data, sizeof h);
    if ((size_t)len != sizeof h + 3 * (size_t)h.w * h.h * sizeof(float)) continue;
    cv_image img = {.w = h.w, .h = h.h, .c = 3, .px = (float *)(void *)(uintptr_t)(data + sizeof h)};
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
    int got = 0;
    while ((len = cv_mailbox_take(we->state_mb, &data, NULL)) >= 0) {
      cv_err err;
      cv_frame_state t;
      if (cv_frame_state_unpack(data, (size_t)len, &t, &err)) {
        fprintf(stderr, "cave run: rank %d: %s (state dropped)\n", we->s->rank, err.msg);
        continue;
      }
      *fs = t;
      if (hash) *hash = cv_hash64(data, (size_t)len);
      got = 1;
      if (t.flags & CV_FS_QUIT) return 0;
      break; /* one frame at a time: later states stay queued */
    }
    if (got) return 1;
    idle(we);
    if (*we->s->stop) {
      if (stop_since == 0) stop_since = cv_service_now();
      else if (cv_service_now() - stop_since > 5) return 0;
    }
    nap();
  }
}

static int write_outputs(walleye *we, const cv_frame_state *fs, cv_err *err) {
  const char *wn = we->s->cave.walls[we->wall].name;
  char path[CV_PATHLEN + 96];
  snprintf(path, sizeof path, "%s/frame%05u_%s_%s.exr", we->s->o.out_dir, fs->frame, wn,
           we->eye ? "R" : "L");
  int st = cv_exr_write(path, we->hdr, 1, CV_EXR_ZIP, err);
  if (st) return st;
  /* PNG: compensated display values through the Rec.709 transfer. */
  cv_image *png;
  st = cv_image_create(we->w, we->h, 3, &png);
  if (st) return cv_err_set(err, st, "out of memory");
  for (size_t i = 0; i < 3 * (size_t)we->w * we->h; i++)
    png->px[i] = (float)cv_rec709_transfer(we->out->px[i]);
  snprintf(path, sizeof path, "%s/frame%05u_%s_%s.png", we->s->o.out_dir, fs->frame, wn,
           we->eye ? "R" : "L");
  st = cv_service_write_png01(path, png, err);
  if (st == CV_OK && we->eye == 0) {
    /* the master assembles the left eye's montage */
    size_t n = sizeof(cv_patch_msg) + 2 * sizeof(int32_t) + 3 * (size_t)we->w * we->h * sizeof(float);
    uint8_t *buf = malloc(n);
    if (buf) {
      cv_patch_msg pm = {.frame = fs->frame, .n = (uint32_t)we->wall};
      int32_t wh[2] = {we->w, we->h};
      memcpy(buf, &pm, sizeof pm);
      memcpy(buf + sizeof pm, wh, sizeof wh);
      memcpy(buf + sizeof pm + sizeof wh, png->px, 3 * (size_t)we->w * we->h * sizeof(float));
      cv_comm_send(buf, n, 0, CV_TAG_IMAGE);
      free(buf);
    }
  }
  cv_image_destroy(png);
  return st;
}

int cv_walleye_run(cv_service *s) {
  walleye WE;
  memset(&WE, 0, sizeof WE);
  walleye *we = &WE;
  we->s = s;
  we->wall = (s->rank - 1) / 2;
  we->eye = (s->rank - 1) % 2;
  cv_err err;
  cv_err_clear(&err);
  int st = walleye_setup(we, &err);
  {
    char msg[700];
    snprintf(msg, sizeof msg, "wall-eye %s/%s: %s", s->cave.walls[we->wall].name, we->eye ? "right" : "left",
             err.msg);
    cv_service_ready(st == CV_OK, msg);
  }
  if (st) {
    /* wait for the master's quit so the job ends cleanly */
    cv_frame_state fs;
    if (we->state_mb) while (next_state(we, &fs, NULL)) {}
    walleye_free(we);
    cv_comm_flush(2);
    return 1;
  }
  const cv_wall *W = &s->cave.walls[we->wall];
  const double half_angle = 0.5 * s->cave.foveal_deg * M_PI / 180.0;
  cv_frame_state fs;
  int rc = 0;
  uint64_t state_hash = 0;
  while (next_state(we, &fs, &state_hash)) {
    const double t0 = cv_service_now();
    if (we->lw) cv_lcd_worker_post(we->lw, &fs);
    cv_frame_timing tm;
    memset(&tm, 0, sizeof tm);
    /* Lighting. */
    if (!we->have_light || fs.light_key != we->light_key) {
      cv_lighting l;
      memset(&l, 0, sizeof l);
      l.bands = fs.bands;
      memcpy(l.sh, fs.sh, sizeof l.sh);
      l.has_sun = fs.has_sun;
      memcpy(l.sun_dir, fs.sun_dir, sizeof l.sun_dir);
      memcpy(l.sun_E, fs.sun_E, sizeof l.sun_E);
      cv_image *bg = NULL;
      cv_lighting unused;
      if (cv_renderer_set_lighting(we->r, &l, NULL, &tm, &err) ||
          cv_service_lighting(s, we->mix, &fs.drive, fs.bands, &unused, 512, &bg, &err) ||
          cv_renderer_set_background(we->r, bg, &err)) {
        fprintf(stderr, "cave run: rank %d: lighting: %s\n", s->rank, err.msg);
      } else {
        we->light_key = fs.light_key;
        we->have_light = 1;
      }
      cv_image_destroy(bg);
    }
    /* This eye's off-axis view. */
    double eyes[2][3];
    cv_head_eyes(fs.head, fs.gaze, s->cave.eye_separation, eyes[0], eyes[1]);
    cv_render_view v;
    memset(&v, 0, sizeof v);
    int vst = cv_offaxis_compute(W->pa, W->pb, W->pc, eyes[we->eye], s->cave.near, s->cave.far, &v.proj);
    memcpy(v.scene_offset, s->cave.scene_offset, sizeof v.scene_offset);
    v.w = we->w;
    v.h = we->h;
    v.supersample = s->cave.supersample;
    cv_drago d;
    cv_drago_default(&d);
    d.bias = s->cave.drago_bias;
    d.ldmax = s->cave.drago_ldmax;
    d.lwa = fs.lwa;
    d.lwmax = fs.lwmax;
    cv_drago_consts dc;
    cv_drago_prepare(&d, &dc);
    cv_walleye_report rep;
    memset(&rep, 0, sizeof rep);
    rep.frame = fs.frame;
    rep.rank = s->rank;
    rep.wall = we->wall;
    rep.eye = we->eye;
    rep.state_hash = state_hash;
    if (vst || cv_renderer_frame(we->r, &v, &dc, 0, we->disp_img, we->hdr, we->lum, &tm, &err)) {
      /* head behind this wall or a GL failure: black frame, no statistics */
      if (!vst) fprintf(stderr, "cave run: rank %d: frame %u: %s\n", s->rank, fs.frame, err.msg);
      memset(we->disp_img->px, 0, 3 * (size_t)we->w * we->h * sizeof(float));
      memset(we->hdr->px, 0, 3 * (size_t)we->w * we->h * sizeof(float));
    } else {
      /* Foveal statistics from the head position (the cone of the gaze). */
      cv_lumstats ls;
      memset(&ls, 0, sizeof ls);
      if (cv_foveal_touches(W->pa, W->pb, W->pc, fs.head, fs.gaze, half_angle))
        cv_foveal_accumulate(we->lum->px, we->lum->w, we->lum->h, W->pa, W->pb, W->pc, fs.head,
                             fs.gaze, half_angle, &ls);
      rep.sum_log = ls.sum_log;
      rep.weight = ls.weight;
      rep.n_pixels = ls.n_pixels;
      rep.n_invalid = ls.n_invalid;
      /* max_l: the largest luminance of the whole pass (Drago's Lwmax). */
      double mx = 0;
      for (size_t i = 0; i < (size_t)we->lum->w * we->lum->h; i++)
        if (isfinite(we->lum->px[i]) && we->lum->px[i] > mx) mx = we->lum->px[i];
      rep.max_l = mx;
    }
    rep.ms_lum = tm.lum_ms + tm.lum_read_ms;
    rep.ms_depth = tm.depth_ms;
    rep.ms_shade = tm.shade_ms + tm.background_ms + tm.resolve_ms;
    rep.ms_read = tm.read_ms;
    /* Report (+ patch means) to the master. */
    size_t np = 0;
    if (we->disp) {
      np = (size_t)we->S->nu * we->S->nv;
      cv_downsample_to_patches(we->disp_img, we->S->nu, we->S->nv, we->S->edge_u, we->S->edge_v,
                               we->patch);
    }
    rep.ms_total = (cv_service_now() - t0) * 1e3;
    rep.ms_lcd = we->lcd_ms;
    rep.lcd_rounds_done = we->lcd_rounds_done;
    size_t len = CV_WALLEYE_REPORT_BYTES + (we->disp ? sizeof(cv_patch_msg) + 3 * np * sizeof(float) : 0);
    uint8_t *buf = malloc(len);
    if (buf && cv_walleye_report_pack(&rep, buf) == CV_OK) {
      if (we->disp) {
        cv_patch_msg pm = {.frame = fs.frame, .n = (uint32_t)np};
        memcpy(buf + CV_WALLEYE_REPORT_BYTES, &pm, sizeof pm);
        float *px = (float *)(void *)(buf + CV_WALLEYE_REPORT_BYTES + sizeof pm);
        for (size_t i = 0; i < 3 * np; i++) px[i] = (float)we->patch[i];
      }
      cv_comm_send(buf, len, 0, CV_TAG_REPORT);
    }
    free(buf);
    /* Compensation: this frame's correction, or the last one if late. */
    if (we->disp) {
      const double deadline =
          cv_service_now() + (fs.frame == 0 ? fmax(s->o.timeout_ms * 1e-3, s->o.startup_timeout_s)
                                            : s->o.timeout_ms * 1e-3);
      int got = 0;
      while (!got) {
        const uint8_t *data;
        long l;
        while ((l = cv_mailbox_take(we->corr_mb, &data, NULL)) >= 0) {
          cv_patch_msg pm;
          if ((size_t)l != sizeof pm + 3 * np * sizeof(float)) continue;
          memcpy(&pm, data, sizeof pm);
          if (pm.n != np) continue;
          memcpy(we->delta, data + sizeof pm, 3 * np * sizeof(float));
          we->have_delta = 1;
          if (pm.frame == fs.frame) {
            got = 1;
            break;
          }
        }
        if (got || cv_service_now() > deadline || *s->stop) break;
        idle(we);
        nap();
      }
      if (!got) we->late_corr++;
      if (we->have_delta) {
        double *dd = malloc(3 * np * sizeof *dd);
        if (dd) {
          for (size_t i = 0; i < 3 * np; i++) dd[i] = we->delta[i];
          cv_apply_patch_delta(we->disp_img, dd, we->S->nu, we->S->nv, we->S->edge_u, we->S->edge_v,
                               we->out);
          free(dd);
        }
      } else {
        memcpy(we->out->px, we->disp_img->px, 3 * (size_t)we->w * we->h * sizeof(float));
      }
    } else {
      memcpy(we->out->px, we->disp_img->px, 3 * (size_t)we->w * we->h * sizeof(float));
    }
    if (fs.flags & CV_FS_WRITE) {
      if (write_outputs(we, &fs, &err)) {
        fprintf(stderr, "cave run: rank %d: %s\n", s->rank, err.msg);
        rc = 1;
      }
    }
    idle(we);
  }
  if (we->lw) cv_lcd_worker_send_ready(we->lw, send_to_master, NULL, NULL, NULL);
  cv_comm_flush(5);
  walleye_free(we);
  return rc;
}
