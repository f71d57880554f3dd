/* The desktop preview (`--present desktop`, issue 11 deliverable 6; see
 * docs/desktop.md): the master's own window on its $DISPLAY, for people
 * without a CAVE.
 *   - cadence: the master marks a frame CV_FS_PREVIEW when --desktop-fps
 *     allows one (at most F a second by the master's clock; 0: every frame);
 *   - the left-eye render ranks of the walls shown send that frame's
 *     uncompensated tone-mapped image as 8-bit codes (CV_TAG_PREVIEW);
 *   - once every shown wall of a preview frame is in, the master composes
 *     the cross (the montages' layout, view/montage.h) or the one wall and
 *     puts it into the window (render/desktop.h); the images go out before
 *     the ranks' reports, so a frame's preview is complete when the frame
 *     is; one overtaken by a newer frame before it is complete (a rank
 *     late) is dropped;
 *   - the window's keyboard and mouse are the head tracker unless a head
 *     path or DTrack is given (cv_head_nav): every read of the X queue is
 *     a tracker sample, stamped with the master's clock when it was read
 *     (as a DTrack packet at its receipt, or a head path sampled each
 *     frame), whether or not it moved the head; the last input's time is
 *     reported apart (desktop.input_age_s);
 *   - Escape, closing the window or a lost X connection stop the service
 *     as a wall-eye window's request does (stop_code, stop_reason). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "comm.h"
#include "master_internal.h"
#include "view/gazeview.h"
#include "view/label.h"
#include "view/montage.h"

#define DESK_STEP_M 0.05       /* head step per key press */
#define DESK_DEG_PER_PX 0.25   /* gaze turn per pixel of drag */
#define DESK_MARGIN_M 0.10     /* the head keeps this far from the screens */
#define DESK_FOV_DEG 90.0      /* the view along the gaze, across */
#define DESK_GAZE_MAX 240      /* its rays across, at most */

/* the rendered size: --size already applied to res (cv_cave_fit_res) */
static int wall_w(const master *m, int w) { return m->s->cave.walls[w].res[0]; }
static int wall_h(const master *m, int w) { return m->s->cave.walls[w].res[1]; }

/* The walls' picture: the montage's cross, or the one wall. */
static int picture_layout(master *m, cv_err *err) {
  const cv_service *s = m->s;
  const int view = s->o.desktop_view;
  if (view >= 0) {
    m->cell_x[view] = m->cell_y[view] = 0;
    m->desk_pic_w = wall_w(m, view), m->desk_pic_h = wall_h(m, view);
    m->desk_walls = 1;
    m->desk_label = cv_montage_label_scale(wall_w(m, view));
    return CV_OK;
  }
  int ws[CV_CAVE_MAX_WALLS], hs[CV_CAVE_MAX_WALLS], mw = 0;
  for (int w = 0; w < s->n_walls; w++) {
    ws[w] = wall_w(m, w), hs[w] = wall_h(m, w);
    if (ws[w] > mw) mw = ws[w];
  }
  m->desk_walls = s->n_walls;
  m->desk_label = cv_montage_label_scale(mw); /* as the montages' (view/montage.h) */
  return cv_montage_layout(&s->cave, ws, hs, m->cell_x, m->cell_y, &m->desk_pic_w, &m->desk_pic_h, err);
}

/* The composed image: the walls' picture, the view along the gaze right of
 * it (as tall), three readout lines below both. */
static int desktop_layout(master *m, cv_err *err) {
  int st = picture_layout(m, err);
  if (st) return st;
  m->desk_gaze_n = m->desk_pic_h;
  m->desk_band = 3 * cv_label_height(m->desk_label) + 2 * m->desk_label;
  m->desk_w = m->desk_pic_w + m->desk_gaze_n;
  m->desk_h = m->desk_pic_h + m->desk_band;
  return CV_OK;
}

/* The box the keyboard head stays in: the walls' bounding box, a margin in. */
static void head_box(const cv_cave *c, double lo[3], double hi[3]) {
  for (int a = 0; a < 3; a++) lo[a] = 1e300, hi[a] = -1e300;
  for (int w = 0; w < c->n_walls; w++) {
    const cv_wall *W = &c->walls[w];
    for (int a = 0; a < 3; a++) {
      const double pd = W->pb[a] + W->pc[a] - W->pa[a], v[4] = {W->pa[a], W->pb[a], W->pc[a], pd};
      for (int k = 0; k < 4; k++) {
        if (v[k] < lo[a]) lo[a] = v[k];
        if (v[k] > hi[a]) hi[a] = v[k];
      }
    }
  }
  for (int a = 0; a < 3; a++) {
    const double mid = 0.5 * (lo[a] + hi[a]);
    lo[a] = lo[a] + DESK_MARGIN_M < mid ? lo[a] + DESK_MARGIN_M : mid;
    hi[a] = hi[a] - DESK_MARGIN_M > mid ? hi[a] - DESK_MARGIN_M : mid;
  }
  /* the configured head is always reachable */
  for (int a = 0; a < 3; a++) {
    if (c->head[a] < lo[a]) lo[a] = c->head[a];
    if (c->head[a] > hi[a]) hi[a] = c->head[a];
  }
}

static int desktop_head_setup(master *m, cv_err *err) {
  const cv_service *s = m->s;
  m->desk_source = !s->o.head_path[0] && s->o.dtrack_port <= 0;
  if (!m->desk_source) return CV_OK;
  double lo[3], hi[3];
  head_box(&s->cave, lo, hi);
  const double now = cv_service_now();
  int st = cv_head_nav_init(&m->nav, s->cave.head, s->cave.gaze, lo, hi, DESK_STEP_M, DESK_DEG_PER_PX, now, err);
  if (st) return st;
  m->pose = m->nav.pose;
  m->pose_time = now;
  return CV_OK;
}

int master_desktop_setup(master *m, cv_err *err) {
  cv_service *s = m->s;
  if (!(s->o.present & CV_PRESENT_DESKTOP)) return CV_OK;
  int st = desktop_layout(m, err);
  if (st) return st;
  char title[96];
  snprintf(title, sizeof title, "cave desktop preview (%s)",
           s->o.desktop_view < 0 ? "cross" : s->cave.walls[s->o.desktop_view].name);
  /* the window: the largest whole scale within 80% of the screen, pixels crisp */
  st = cv_desktop_open_scaled(NULL, title, m->desk_w, m->desk_h, 0.8, &m->desk_win_k, &m->desk, err);
  if (st) {
    cv_err_prefix(err, "--present desktop");
    return st;
  }
  m->desk_rgb = calloc(3 * (size_t)m->desk_w * m->desk_h, 1);
  m->prev_mb = calloc((size_t)s->n_walls, sizeof *m->prev_mb);
  if (!m->desk_rgb || !m->prev_mb) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
  for (int w = 0; w < s->n_walls; w++) {
    if (s->o.desktop_view >= 0 && s->o.desktop_view != w) continue;
    const size_t cap = sizeof(cv_preview_msg) + 3 * (size_t)wall_w(m, w) * wall_h(m, w);
    m->prev_mb[w] = cv_mailbox_open(cv_cave_walleye_rank(&s->cave, w, 0), CV_TAG_PREVIEW, cap);
    if (!m->prev_mb[w]) return cv_err_set(err, CV_ERR_NOMEM, "master: cannot post receives");
  }
  /* black until the first preview frame */
  if ((st = cv_desktop_show(m->desk, m->desk_rgb, m->desk_w, m->desk_h, err))) return st;
  m->desk_frame = 0xffffffffu;
  return desktop_head_setup(m, err);
}

void master_desktop_free(master *m) {
  for (int w = 0; m->prev_mb && w < m->s->n_walls; w++) cv_mailbox_close(m->prev_mb[w]);
  free(m->prev_mb);
  free(m->desk_rgb);
  cv_desktop_destroy(m->desk);
  m->prev_mb = NULL;
  m->desk_rgb = NULL;
  m->desk = NULL;
}

int master_desktop_mark(master *m, uint32_t f, const double head[3], const double gaze[3]) {
  m->desk_marked = 0;
  if (!m->desk) return 0;
  const double now = cv_service_now(), fps = m->s->o.desktop_fps;
  if (fps > 0 && m->desk_last_mark > 0 && now - m->desk_last_mark < 1.0 / fps) return 0;
  m->desk_last_mark = now;
  m->desk_marked = 1;
  m->desk_pose[f % 8].frame = f; /* for the view along the gaze of this frame */
  memcpy(m->desk_pose[f % 8].head, head, sizeof m->desk_pose[0].head);
  memcpy(m->desk_pose[f % 8].gaze, gaze, sizeof m->desk_pose[0].gaze);
  m->desk_marks++;
  return 1;
}

/* The three readout lines: frame and rate, head and gaze, each LCD
 * panel's contrast ratio. */
static void readouts(master *m, const double *head, const double *gaze, char *txt, size_t cap) {
  const cv_service *s = m->s;
  const double yaw = atan2(gaze[0], -gaze[2]) * 180 / M_PI;
  const double pitch = asin(fmax(-1, fmin(1, gaze[1] / sqrt(gaze[0] * gaze[0] + gaze[1] * gaze[1] + gaze[2] * gaze[2])))) * 180 / M_PI;
  size_t l = (size_t)snprintf(txt, cap, "frame %u  %.1f fps\nhead %.2f %.2f %.2f m  gaze yaw %.0f pitch %.0f deg\n",
                              m->desk_frame, m->desk_fps, head[0], head[1], head[2], yaw, pitch);
  if (!m->lcd_mb) {
    snprintf(txt + l, cap - l, "LCD off (--no-lcd)");
  } else if (!m->lread.valid) {
    snprintf(txt + l, cap - l, "LCD CR: no estimate yet");
  } else {
    l += (size_t)snprintf(txt + l, cap - l, "CR");
    for (int i = 0; i < s->lcd_layout.n && l < cap; i++)
      l += (size_t)snprintf(txt + l, cap - l, " %s %.1f", s->lcd.panels[i].name, m->lread.p[i].cr.value);
    if (l < cap) snprintf(txt + l, cap - l, " (need %.0f:1)", m->lread.cr_min);
  }
}

/* Labels, the view along the gaze and the readouts around the walls. */
static void desktop_compose(master *m) {
  const cv_service *s = m->s;
  const cv_cave *c = &s->cave;
  static const uint8_t white[3] = {255, 255, 255}, yellow[3] = {255, 255, 160};
  const double now = cv_service_now();
  if (m->desk_fps_t0 <= 0) m->desk_fps_t0 = now, m->desk_fps_n0 = m->nframes_done;
  else if (now - m->desk_fps_t0 >= 1.0) {
    m->desk_fps = (double)(m->nframes_done - m->desk_fps_n0) / (now - m->desk_fps_t0);
    m->desk_fps_t0 = now, m->desk_fps_n0 = m->nframes_done;
  }
  const double *head = c->head, *gaze = c->gaze;
  if (m->desk_pose[m->desk_frame % 8].frame == m->desk_frame)
    head = m->desk_pose[m->desk_frame % 8].head, gaze = m->desk_pose[m->desk_frame % 8].gaze;
  /* traced at most DESK_GAZE_MAX pixels across (a ray per pixel on the master's thread), then enlarged */
  const int n = m->desk_gaze_n, g = n < DESK_GAZE_MAX ? n : DESK_GAZE_MAX;
  uint8_t *gv = malloc(3 * (size_t)g * g);
  if (gv) {
    int ws[CV_CAVE_MAX_WALLS], hs[CV_CAVE_MAX_WALLS];
    for (int w = 0; w < s->n_walls; w++) ws[w] = wall_w(m, w), hs[w] = wall_h(m, w);
    cv_gaze_view(c, m->desk_rgb, m->desk_w, m->cell_x, m->cell_y, ws, hs, m->desk_have, head, gaze, DESK_FOV_DEG, gv, g);
    for (int y = 0; y < n; y++)
      for (int x = 0; x < n; x++)
        memcpy(m->desk_rgb + 3 * ((size_t)y * m->desk_w + m->desk_pic_w + x),
               gv + 3 * ((size_t)(y * g / n) * g + (size_t)x * g / n), 3);
    free(gv);
    cv_label_draw(m->desk_rgb, m->desk_w, m->desk_pic_h, m->desk_pic_w + m->desk_label, m->desk_label, m->desk_label,
                  "view along the gaze", yellow);
  }
  for (int w = 0; s->o.desktop_view < 0 && w < s->n_walls; w++) /* one wall: named in the title */
    if (m->desk_have[w])
      cv_label_draw(m->desk_rgb, m->desk_w, m->desk_pic_h, m->cell_x[w] + m->desk_label, m->cell_y[w] + m->desk_label,
                    m->desk_label, c->walls[w].name, yellow);
  memset(m->desk_rgb + 3 * (size_t)m->desk_pic_h * m->desk_w, 0, 3 * (size_t)m->desk_band * m->desk_w);
  char txt[600];
  readouts(m, head, gaze, txt, sizeof txt);
  cv_label_draw(m->desk_rgb, m->desk_w, m->desk_h, m->desk_label, m->desk_pic_h + m->desk_label, m->desk_label, txt,
                white);
}

static void desktop_show(master *m) {
  const double t0 = cv_service_now();
  desktop_compose(m);
  cv_err err;
  if (cv_desktop_show(m->desk, m->desk_rgb, m->desk_w, m->desk_h, &err) == CV_OK) m->desk_shown++;
  m->desk_show_ms = (cv_service_now() - t0) * 1e3;
}

/* One preview image into its cell; shows the frame when it is complete. */
static void desktop_take(master *m, int w, const uint8_t *data, long len) {
  cv_preview_msg h;
  if ((size_t)len < sizeof h) return;
  memcpy(&h, data, sizeof h);
  if (h.wall != w || h.w != wall_w(m, w) || h.h != wall_h(m, w) ||
      (size_t)len != sizeof h + 3 * (size_t)h.w * h.h)
    return;
  if (m->desk_frame != 0xffffffffu && h.frame < m->desk_frame) return; /* an overtaken frame's */
  if (h.frame != m->desk_frame) {
    m->desk_frame = h.frame;
    m->desk_got = 0;
    memset(m->desk_have, 0, sizeof m->desk_have);
  }
  if (m->desk_have[w]) return;
  const uint8_t *px = data + sizeof h;
  for (int y = 0; y < h.h; y++)
    memcpy(m->desk_rgb + 3 * ((size_t)(m->cell_y[w] + y) * m->desk_w + m->cell_x[w]), px + 3 * (size_t)y * h.w,
           3 * (size_t)h.w);
  m->desk_have[w] = 1;
  if (++m->desk_got == m->desk_walls) desktop_show(m);
}

void master_desktop_drain(master *m) {
  if (!m->desk) return;
  for (int w = 0; w < m->s->n_walls; w++) {
    if (!m->prev_mb[w]) continue;
    const uint8_t *data;
    long len;
    while ((len = cv_mailbox_take(m->prev_mb[w], &data, NULL)) >= 0) desktop_take(m, w, data, len);
  }
}

void master_desktop_poll(master *m, double now) {
  if (!m->desk) return;
  cv_desktop_input in;
  memset(&in, 0, sizeof in);
  const int ev = cv_desktop_poll(m->desk, &in);
  m->desk_polled = now;
  if (m->desk_source) {
    const cv_head_nav_input ni = {.right = in.right, .forward = in.forward, .up = in.up,
                                  .drag_x = in.drag_x, .drag_y = in.drag_y, .reset = in.reset};
    if (in.events) cv_head_nav_apply(&m->nav, &ni, now);
    m->prev_pose = m->pose;
    m->prev_pose_time = m->pose_time;
    m->pose = m->nav.pose;
    m->pose.t = now;
    m->pose_time = now;
  }
  if (ev != CV_WIN_OK && !m->stop_code) {
    m->stop_code = ev;
    snprintf(m->stop_reason, sizeof m->stop_reason, "desktop window (rank 0, X display '%s'): %s",
             cv_desktop_display_name(m->desk), cv_window_event_name(ev));
    fprintf(stderr, "cave run: stopping: %s\n", m->stop_reason);
  }
}

void master_desktop_metrics(master *m, cv_metrics_line *ml) {
  if (!m->desk) return;
  cv_metrics_object_begin(ml, "desktop");
  cv_metrics_bool(ml, "preview_frame", m->desk_marked);
  cv_metrics_uint(ml, "shown", m->desk_shown);
  cv_metrics_double(ml, "show_ms", m->desk_show_ms);
  if (m->desk_source) {
    cv_metrics_uint(ml, "inputs", m->nav.inputs);
    cv_metrics_double(ml, "input_age_s", cv_service_now() - m->nav.pose.t);
  }
  cv_metrics_object_end(ml);
}

void master_desktop_summary(master *m, cv_metrics_line *ml) {
  if (!m->desk) return;
  cv_metrics_uint(ml, "desktop_preview_frames", m->desk_marks);
  cv_metrics_uint(ml, "desktop_previews", m->desk_shown);
  if (m->desk_source) cv_metrics_uint(ml, "desktop_inputs", m->nav.inputs);
}
