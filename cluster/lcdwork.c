/* LCD final-gather contributor, shared by the gather-only ranks and the
 * wall-eyes' idle threads: a worker thread that renders this contributor's
 * rounds (round = index + k * contributors, k = 0, 1, ...; with dead gather
 * ranks also its part of theirs, lcdshare.h) of the current key until the
 * budget, in increasing order, and queues each finished round as a message for the
 * owning (MPI) thread to send.  The owner posts frame states; each round
 * takes the newest as its snapshot: the worker rebuilds the lighting when
 * the light key changed and restarts its rounds when the LCD key (quantised
 * eye, lighting) changed.  Everything a round
 * depends on is a function of the key, so the master may add rounds from any
 * contributor: the sum is the same integers for any rank count. */
#define _GNU_SOURCE 1 /* SCHED_IDLE */
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "lcd/brdf.h"
#include "lcd/gather.h"
#include "lcd/light_level.h"
#include "lcd/panels.h"
#include "light/envmap_cache.h"
#include "lcdwork.h"
#include "prt/bake.h"
#include "service/lcdshare.h"
#include "service_internal.h"

typedef struct msg_node {
  uint8_t *buf;
  size_t len;
  struct msg_node *next;
} msg_node;

struct cv_lcd_worker {
  const cv_service *s;
  const cv_prt *prt;
  int index, idle;
  cv_mesh *mesh;
  cv_tracer *tr;
  cv_lcd_panels *ps;    /* the scene config's panels (s->lcd), as `cave lcd` renders them */
  cv_lcd_params p;
  cv_lcd_veil_params vp;
  cv_lcd_figure veil[CV_LCD_MAX_PANELS]; /* of the current key (traced once per key) */
  int have_veil;
  double light[3]; /* the key's light level (light_level.h), carried like the veils */
  cv_envmap_cache *maps; /* the drive's env maps, decoded once (the worker thread's) */
  /* state shared with the owner (mutex) */
  pthread_mutex_t mu;
  pthread_cond_t cv;
  int have_state, quit;
  cv_frame_state posted;
  uint64_t posted_seq;
  msg_node *head, *tail;
  size_t queued;
  uint64_t rounds_done;
  double ms_total, cpu_ms_total; /* rounds' wall and thread CPU time */
  /* the rounds of the current key (shared with cv_lcd_worker_redo): those
   * taken (rendered or being rendered), the lowest that may still be this
   * contributor's and not taken, the dead gather ranks of the ownership */
  uint8_t *taken;
  uint32_t cursor;
  uint64_t dead;
  uint32_t floor; /* the master has the dead ones' rounds of the current key below it */
  int have_cur;
  cv_lcd_key cur;
  char error[640];
  pthread_t th;
  int started;
};

static int worker_init(cv_lcd_worker *w, cv_err *err) {
  int st = cv_prt_to_mesh(w->prt, &w->mesh);
  if (st) return cv_err_set(err, st, "LCD: cannot rebuild the scene mesh from %s", w->s->o.scene_path);
  st = cv_tracer_create(w->mesh, &w->tr, err);
  if (st) return st;
  const cv_lcd_config *lc = &w->s->lcd;
  st = cv_lcd_panels_create(lc, &w->s->lcd_layout, cv_tracer_rt(w->tr), w->mesh, &w->ps, err);
  if (st) return st;
  cv_lcd_params_default(&w->p);
  w->p.w = w->s->lcd_layout.w[0];
  w->p.h = w->s->lcd_layout.h[0];
  w->p.spp = lc->spp;
  w->p.seed = lc->seed;
  w->p.brdf_fraction = lc->brdf_fraction;
  w->p.threads = 1;
  cv_lcd_veil_params_default(&w->vp);
  w->vp.age = lc->age;
  w->vp.pigment = lc->pigment;
  return CV_OK;
}

/* The lighting of the frame state fs (the round's snapshot), replacing *ll.
 * Returns CV_OK or an error in err. */
static int snapshot_lighting(cv_lcd_worker *w, const cv_frame_state *fs, cv_lcd_light **ll,
                             cv_err *err) {
  cv_scene_light *sl = NULL;
  cv_light_spec spec;
  cv_drive_to_light_spec(w->s->drive, &fs->drive, &spec);
  cv_lcd_light *nl = NULL;
  int st = cv_scene_light_build_cached(&spec, (int)w->prt->bands, w->maps, &sl, err);
  if (st == CV_OK)
    st = cv_lcd_light_from_scene(sl, &spec, w->prt, w->tr, w->s->lcd.sun_samples,
                                 w->s->lcd.env_width, &nl, err);
  cv_scene_light_destroy(sl);
  if (st) return st;
  cv_lcd_light_destroy(*ll);
  *ll = nl;
  return CV_OK;
}

static void worker_error(cv_lcd_worker *w, const char *what, const char *msg) {
  pthread_mutex_lock(&w->mu);
  snprintf(w->error, sizeof w->error, "%s: %s", what, msg);
  pthread_mutex_unlock(&w->mu);
}

/* Renders one round into a message and queues it for the owner. */
static void render_round(cv_lcd_worker *w, const cv_lcd_light *ll, const cv_lcd_key *key,
                         double clamp, uint32_t round, uint32_t frame) {
  struct timespec t0, t1, c0, c1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c0);
  cv_lcd_accum *acc = NULL;
  int st = cv_lcd_accum_create(w->s->lcd_layout.W, w->s->lcd_layout.H, clamp, &acc);
  if (st == CV_OK) st = cv_lcd_panels_round(w->ps, ll, &w->p, round, acc);
  for (int i = 0; st == CV_OK && w->have_veil && i < w->s->lcd_layout.n; i++)
    st = cv_lcd_accum_set_veil(acc, i, w->veil[i].value, w->veil[i].se);
  if (st == CV_OK) st = cv_lcd_accum_set_light(acc, w->light);
  if (st != CV_OK) {
    cv_lcd_accum_destroy(acc);
    char m[64];
    snprintf(m, sizeof m, "round %u failed", round);
    worker_error(w, "LCD", m);
    return;
  }
  clock_gettime(CLOCK_MONOTONIC, &t1);
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c1);
  cv_lcd_msg h;
  memset(&h, 0, sizeof h);
  h.key = *key;
  h.round = round;
  h.w = acc->w;
  h.h = acc->h;
  h.contributor = (uint32_t)w->index;
  h.clamp = clamp;
  h.n = acc->n;
  h.frame = frame;
  msg_node *node = malloc(sizeof *node);
  uint8_t *buf = malloc(sizeof h + acc->n * sizeof(int64_t));
  if (node && buf) {
    memcpy(buf, &h, sizeof h);
    memcpy(buf + sizeof h, acc->data, acc->n * sizeof(int64_t));
    node->buf = buf;
    node->len = sizeof h + acc->n * sizeof(int64_t);
    node->next = NULL;
    pthread_mutex_lock(&w->mu);
    if (w->tail) w->tail->next = node;
    else w->head = node;
    w->tail = node;
    w->queued++;
    w->rounds_done++;
    w->ms_total += (double)(t1.tv_sec - t0.tv_sec) * 1e3 + (double)(t1.tv_nsec - t0.tv_nsec) * 1e-6;
    w->cpu_ms_total += (double)(c1.tv_sec - c0.tv_sec) * 1e3 + (double)(c1.tv_nsec - c0.tv_nsec) * 1e-6;
    pthread_mutex_unlock(&w->mu);
  } else {
    free(node);
    free(buf);
  }
  cv_lcd_accum_destroy(acc);
}

/* The lowest round of the current key this contributor owns (under the
 * dead gather ranks it knows of) and has not taken; the budget when none.
 * Called with the mutex held. */
static uint32_t next_owned(cv_lcd_worker *w) {
  const uint32_t budget = (uint32_t)w->s->o.lcd_budget;
  const int first_gather = w->s->o.lcd_idle ? w->s->n_render : 0;
  const int count = w->s->n_contributors;
  while (w->cursor < budget &&
         (w->taken[w->cursor] ||
          cv_lcd_round_owner(w->cursor, count, first_gather, w->dead) != w->index ||
          (w->cursor < w->floor && cv_lcd_contributor_dead((int)(w->cursor % (uint32_t)count), first_gather, w->dead))))
    w->cursor++;
  return w->cursor;
}

/* Each round is a snapshot: before it starts, the newest posted frame state
 * gives its lighting (rebuilt only when the light key changed) and its eye,
 * and the round finishes with them whatever arrives meanwhile.  While the
 * car turns every round has a key of its own (the master reports it with
 * its key and age); while the head and the lighting hold still the rounds
 * of one key accumulate to the budget.  At most one lighting build per
 * round, so a turning car costs the wall-eyes no more than a held one. */
static void *worker_main(void *arg) {
  cv_lcd_worker *w = arg;
  cv_rt_thread_init();
  /* A wall-eye's LCD thread is an idle thread, as the paper's idle CPUs: it
   * runs when the render threads of this machine do not need the cores
   * (SCHED_IDLE, Linux).  A gather rank's thread is its rank's whole job. */
  if (w->idle) {
    struct sched_param sp = {.sched_priority = 0};
    pthread_setschedparam(pthread_self(), SCHED_IDLE, &sp);
  }
  uint64_t seen_seq = 0, light_key = 0;
  int have_light = 0, have_key = 0, have_fs = 0;
  cv_lcd_light *ll = NULL;
  cv_lcd_key key;
  double clamp = 1;
  uint32_t key_frame = 0;
  cv_frame_state fs;
  memset(&fs, 0, sizeof fs);
  for (;;) {
    pthread_mutex_lock(&w->mu);
    for (;;) {
      if (w->quit) break;
      if (w->have_state && w->posted_seq != seen_seq) {
        fs = w->posted;
        seen_seq = w->posted_seq;
        have_fs = 1;
        if (fs.lcd_dead != w->dead) { /* a gather rank died: its rounds are shared */
          w->dead = fs.lcd_dead;
          w->cursor = 0;
        }
        /* the dead ones' rounds the master has (of its key, when it is ours) */
        w->floor = w->have_cur && fs.lcd_key == cv_service_lcd_key(w->cur.eye_q, w->cur.light_hash)
                       ? fs.lcd_dead_floor : 0;
      }
      /* work: a newer state than the key's (a new snapshot), or rounds
       * left for the key; at most 4 rounds waiting for the owner */
      const int newer = have_fs && (!have_key || fs.lcd_key != cv_service_lcd_key(key.eye_q, light_key));
      const int left = have_key && next_owned(w) < (uint32_t)w->s->o.lcd_budget;
      if ((newer || left) && w->queued < 4) break;
      pthread_cond_wait(&w->cv, &w->mu);
    }
    const int quit = w->quit;
    pthread_mutex_unlock(&w->mu);
    if (quit) break;
    if (!have_light || fs.light_key != light_key) { /* the round's lighting */
      cv_err err;
      if (snapshot_lighting(w, &fs, &ll, &err) != CV_OK) {
        worker_error(w, "LCD lighting", err.msg);
        have_fs = 0; /* wait for the next state */
        continue;
      }
      light_key = fs.light_key;
      have_light = 1;
      clamp = cv_lcd_panels_clamp(w->ps, ll, w->s->lcd.clamp);
      have_key = 0;
    }
    float eye[3];
    for (int a = 0; a < 3; a++) eye[a] = (float)(fs.head[a] + w->s->cave.scene_offset[a]);
    const uint64_t setup = cv_lcd_panels_setup_hash(w->ps, &w->p, clamp, w->s->o.lcd_tolerance, 0);
    cv_lcd_key nk;
    if (cv_lcd_key_make(eye, w->s->o.lcd_tolerance, light_key, setup, &nk) != CV_OK ||
        cv_service_lcd_key(nk.eye_q, light_key) != fs.lcd_key) { /* not the master's key */
      have_fs = 0;
      continue;
    }
    const int new_key = !have_key || !cv_lcd_key_equal(&nk, &key);
    if (new_key) {
      key = nk;
      have_key = 1;
      key_frame = fs.frame;
      cv_lcd_key_eye(&key, w->s->o.lcd_tolerance, w->p.eye);
      /* the key's veils (a pure function of its eye and lighting: every
       * contributor stores the same values in its rounds) */
      double sun_deg[CV_LCD_MAX_PANELS];
      w->have_veil = cv_lcd_panels_veils(w->ps, ll, w->p.eye, &w->vp, w->veil, sun_deg) == CV_OK;
      /* and its light level: outdoors and at the key's eye */
      cv_lcd_illum il;
      cv_lcd_illuminance(w->ps->g[0], ll, w->p.eye, &il);
      w->light[0] = il.outdoor_h, w->light[1] = il.eye_h, w->light[2] = il.eye_v;
    }
    pthread_mutex_lock(&w->mu);
    if (new_key) { /* its rounds start over */
      memset(w->taken, 0, (size_t)w->s->o.lcd_budget);
      w->cursor = 0;
      w->floor = fs.lcd_dead_floor; /* fs is of this key */
      w->cur = key;
      w->have_cur = 1;
    }
    const uint32_t round = next_owned(w);
    if (round < (uint32_t)w->s->o.lcd_budget) w->taken[round] = 1;
    pthread_mutex_unlock(&w->mu);
    if (round >= (uint32_t)w->s->o.lcd_budget) continue;
    render_round(w, ll, &key, clamp, round, key_frame);
  }
  cv_lcd_light_destroy(ll);
  return NULL;
}

int cv_lcd_worker_create(const cv_service *s, const cv_prt *prt, int index, int idle,
                         cv_lcd_worker **out, cv_err *err) {
  *out = NULL;
  cv_lcd_worker *w = calloc(1, sizeof *w);
  if (!w) return cv_err_set(err, CV_ERR_NOMEM, "LCD worker: out of memory");
  w->s = s;
  w->prt = prt;
  w->index = index;
  w->idle = idle;
  pthread_mutex_init(&w->mu, NULL);
  pthread_cond_init(&w->cv, NULL);
  w->taken = calloc((size_t)(s->o.lcd_budget > 0 ? s->o.lcd_budget : 1), 1);
  int st = w->taken && cv_envmap_cache_create(&w->maps) == CV_OK ? worker_init(w, err) : cv_err_set(err, CV_ERR_NOMEM, "LCD worker: out of memory");
  if (st) {
    cv_lcd_worker_destroy(w);
    return st;
  }
  if (pthread_create(&w->th, NULL, worker_main, w)) {
    cv_lcd_worker_destroy(w);
    return cv_err_set(err, CV_ERR_NOMEM, "LCD worker: cannot start a thread");
  }
  w->started = 1;
  *out = w;
  return CV_OK;
}

void cv_lcd_worker_post(cv_lcd_worker *w, const cv_frame_state *fs) {
  pthread_mutex_lock(&w->mu);
  w->posted = *fs;
  w->have_state = 1;
  w->posted_seq++;
  pthread_cond_signal(&w->cv);
  pthread_mutex_unlock(&w->mu);
}

int cv_lcd_worker_send_ready(cv_lcd_worker *w, int (*send)(const uint8_t *, size_t, void *),
                             void *user, uint64_t *rounds_done, double *ms_total) {
  int n = 0;
  for (;;) {
    pthread_mutex_lock(&w->mu);
    msg_node *node = w->head;
    if (node) {
      w->head = node->next;
      if (!w->head) w->tail = NULL;
      w->queued--;
      pthread_cond_signal(&w->cv);
    }
    if (rounds_done) *rounds_done = w->rounds_done;
    if (ms_total) *ms_total = w->ms_total;
    pthread_mutex_unlock(&w->mu);
    if (!node) break;
    send(node->buf, node->len, user);
    free(node->buf);
    free(node);
    n++;
  }
  return n;
}

void cv_lcd_worker_redo(cv_lcd_worker *w, const cv_lcd_key *key, uint32_t first, uint32_t n) {
  const uint32_t budget = (uint32_t)w->s->o.lcd_budget, stride = (uint32_t)w->s->n_contributors;
  pthread_mutex_lock(&w->mu);
  if (w->have_cur && cv_lcd_key_equal(&w->cur, key)) {
    for (uint64_t i = 0, r = first; i < n && r < budget; i++, r += stride) w->taken[r] = 0;
    if (first < w->cursor) w->cursor = first;
    pthread_cond_signal(&w->cv);
  }
  pthread_mutex_unlock(&w->mu);
}

void cv_lcd_worker_totals(cv_lcd_worker *w, uint64_t *rounds_done, double *ms_total, double *cpu_ms_total) {
  pthread_mutex_lock(&w->mu);
  *rounds_done = w->rounds_done;
  *ms_total = w->ms_total;
  *cpu_ms_total = w->cpu_ms_total;
  pthread_mutex_unlock(&w->mu);
}

const char *cv_lcd_worker_error(cv_lcd_worker *w) { return w->error[0] ? w->error : NULL; }

void cv_lcd_worker_destroy(cv_lcd_worker *w) {
  if (!w) return;
  if (w->started) {
    pthread_mutex_lock(&w->mu);
    w->quit = 1;
    pthread_cond_signal(&w->cv);
    pthread_mutex_unlock(&w->mu);
    pthread_join(w->th, NULL);
  }
  while (w->head) {
    msg_node *n = w->head;
    w->head = n->next;
    free(n->buf);
    free(n);
  }
  cv_lcd_panels_destroy(w->ps);
  cv_tracer_destroy(w->tr);
  cv_mesh_destroy(w->mesh);
  cv_envmap_cache_destroy(w->maps);
  pthread_mutex_destroy(&w->mu);
  pthread_cond_destroy(&w->cv);
  free(w->taken);
  free(w);
}
