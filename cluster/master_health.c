/* The master's heartbeat watch (docs/dead-rank.md).  Open MPI 4 cannot tell
 * a rank that a peer died, and with `mpirun --enable-recovery` the job goes
 * on with the dead process's operations pending for ever.  So the master
 * watches above MPI: gather-only ranks send a heartbeat every 0.25 s
 * (CV_TAG_ALIVE), wall-eyes report every frame.  A rank silent for
 * --gather-timeout seconds is dead:
 *   gather rank  named once on stderr and in the metrics (dead_ranks); no
 *                more states to it; the LCD allreduce, which would wait for
 *                it for ever, is given up on the master, and the surviving
 *                gather ranks, told by the death notice every rank gets
 *                (cv_comm_notify_dead), send their rounds point-to-point
 *                (the render ranks' path); the frames never waited for it;
 *                its LCD rounds go to the live contributors (the frame
 *                state's lcd_dead and lcd_dead_floor, src/service/lcdshare.c).
 * The notice goes to the dead rank too: one only stalled leaves when it
 * runs again.  With a dead rank no rank calls MPI_Finalize (it would wait
 * for it).
 *   wall-eye     (silent: no report for S s while one was owed)
 *                its walls cannot be shown: the run stops cleanly, naming
 *                it (summary stop_reason, exit status 1). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "comm.h"
#include "lcdreduce.h"
#include "master_internal.h"
#include "service/lcdshare.h"

int master_health_setup(master *m) {
  m->alive_t = calloc((size_t)m->s->size, sizeof *m->alive_t);
  m->owed_t = calloc((size_t)m->s->size, sizeof *m->owed_t);
  m->dead = calloc((size_t)m->s->size, 1);
  m->rank_host = calloc((size_t)m->s->size, sizeof *m->rank_host);
  if (!m->alive_t || !m->owed_t || !m->dead || !m->rank_host) return -1;
  if (m->s->n_gather > 0 && !(m->alive_mb = cv_mailbox_open(-1, CV_TAG_ALIVE, 16))) return -1;
  return 0;
}

void master_health_free(master *m) {
  cv_mailbox_close(m->alive_mb);
  free(m->alive_t);
  free(m->owed_t);
  free(m->dead);
  free(m->rank_host);
}

void master_health_host(master *m, int rank, const char *line) {
  if (!m->rank_host || rank <= 0 || rank >= m->s->size || !line) return;
  const char *on = strstr(line, " on "), *end = on ? strchr(on + 4, ':') : NULL;
  if (!on || !end || end - on - 4 >= (long)sizeof m->rank_host[0]) return;
  snprintf(m->rank_host[rank], sizeof m->rank_host[0], "%.*s", (int)(end - on - 4), on + 4);
}

static const char *host_of(const master *m, int rank) {
  return m->rank_host && m->rank_host[rank][0] ? m->rank_host[rank] : "unknown";
}

void master_health_arm(master *m) {
  const double now = cv_service_now();
  for (int r = 0; r < m->s->size; r++) {
    m->alive_t[r] = now;
    m->owed_t[r] = 0;
  }
  m->health_armed = 1;
}

void master_health_seen(master *m, int rank) {
  if (!m->alive_t || rank <= 0 || rank >= m->s->size) return;
  m->alive_t[rank] = cv_service_now();
  if (rank <= m->s->n_render) m->owed_t[rank] = 0;
}

/* A wall-eye counts as silent only while a frame's report is owed (the
 * frames may be paced slower than the timeout). */
void master_health_sent(master *m) {
  if (!m->owed_t) return;
  const double now = cv_service_now();
  for (int r = 1; r <= m->s->n_render; r++)
    if (m->owed_t[r] == 0) m->owed_t[r] = now;
}

/* A gather rank is dead: the allreduce is given up, the others go
 * point-to-point. */
static void gather_dead(master *m, int r, double silent) {
  fprintf(stderr,
          "cave run: master: rank %d (gather-only) silent for %.1f s (host %s): declared dead; "
          "its LCD rounds go to the others\n",
          r, silent, host_of(m, r));
  if (m->lcd_red && !m->lcd_red_abandoned) { /* the others learn it from the notice */
    cv_lcd_reduce_abandon(m->lcd_red);
    m->lcd_red_abandoned = 1;
  }
  /* its rounds: shared by the live contributors from the next frame state on
   * (lcd_dead, lcdshare.h) */
  const int first_gather = m->s->o.lcd_idle ? m->s->n_render : 0;
  const uint64_t dead = master_health_lcd_dead(m);
  int live = 0;
  for (int c = 0; c < m->s->n_contributors; c++) live += !cv_lcd_contributor_dead(c, first_gather, dead);
  if (m->s->o.lcd && live == 0)
    fprintf(stderr, "cave run: master: no LCD contributor is left: the LCD image stays at %u rounds\n",
            m->lcd_rounds);
}

uint64_t master_health_lcd_dead(const master *m) {
  uint64_t d = 0;
  for (int g = 0; m->dead && g < m->s->n_gather && g < 64; g++)
    if (m->dead[1 + m->s->n_render + g]) d |= 1ull << g;
  return d;
}

uint32_t master_health_lcd_floor(const master *m) {
  const uint64_t dead = master_health_lcd_dead(m);
  if (!dead || !m->seen) return 0;
  const int count = m->s->n_contributors, first_gather = m->s->o.lcd_idle ? m->s->n_render : 0;
  uint32_t floor = (uint32_t)m->s->o.lcd_budget;
  for (int c = 0; c < count; c++) {
    if (!cv_lcd_contributor_dead(c, first_gather, dead)) continue;
    uint32_t r = (uint32_t)c;
    while (r < floor && m->seen[r]) r += (uint32_t)count;
    if (r < floor) floor = r;
  }
  return floor;
}

static void walleye_dead(master *m, int r, double silent) {
  if (m->stop_code) return;
  const cv_output *o = &m->s->cave.outputs[r - 1];
  m->stop_code = MASTER_STOP_DEAD;
  snprintf(m->stop_reason, sizeof m->stop_reason,
           "rank %d (wall-eye of wall %d) silent for %.1f s (host %s, output %d: %s, %s): declared dead", r,
           o->wall, silent, host_of(m, r), r - 1, m->s->cave.walls[o->wall].name,
           o->eyes == 3 ? "both eyes" : o->eyes == 1 ? "left eye" : "right eye");
  fprintf(stderr, "cave run: stopping: %s\n", m->stop_reason);
}

void master_health_poll(master *m) {
  if (!m->alive_t) return;
  const uint8_t *data;
  int from;
  while (m->alive_mb && cv_mailbox_take(m->alive_mb, &data, &from) >= 0) master_health_seen(m, from);
  if (!m->health_armed) return;
  const double now = cv_service_now(), tmo = m->s->o.gather_timeout_s;
  for (int r = 1; r < m->s->size; r++) {
    const int wall = r <= m->s->n_render;
    const double silent = wall ? (m->owed_t[r] > 0 ? now - m->owed_t[r] : 0) : now - m->alive_t[r];
    if (m->dead[r] || silent <= tmo) continue;
    m->dead[r] = 1;
    m->ndead++;
    cv_comm_mark_dead(r);
    cv_comm_notify_dead(r);
    if (wall) walleye_dead(m, r, silent);
    else gather_dead(m, r, silent);
  }
}

void master_health_metrics(master *m, cv_metrics_line *ml) {
  double d[64];
  size_t n = 0;
  for (int r = 1; m->dead && r < m->s->size && n < 64; r++)
    if (m->dead[r]) d[n++] = r;
  cv_metrics_doubles(ml, "dead_ranks", d, n);
}
