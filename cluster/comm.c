/* MPI behind the message layer of comm.h. */
#include "comm.h"

#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct pending_send {
  MPI_Request req;
  int dest;
  void *copy;
  int *refs; /* shared copies (cv_comm_send_multi): free at 0; NULL = own copy */
} pending_send;

/* Sends in flight (owned copies).  One process, one thread calls MPI. */
static pending_send *g_sends;
static size_t g_nsends, g_capsends;
/* The render ranks' communicator and its barrier in flight (same rule). */
static MPI_Comm g_render = MPI_COMM_NULL;
static MPI_Request g_barrier = MPI_REQUEST_NULL;
/* per world rank: a member of g_render; the swap barrier given up (a member
 * died: it would never complete) */
static unsigned char *g_in_render;
static int g_barrier_abandoned;
/* The LCD reduction's communicator and its sum in flight (same rule). */
static MPI_Comm g_lcd = MPI_COMM_NULL;
static MPI_Request g_lcd_req = MPI_REQUEST_NULL;
static int g_lcd_abandoned; /* a member died: never waited on (nor freed) again */
/* Shared lighting: the host group of the render ranks and its window. */
static MPI_Comm g_host = MPI_COMM_NULL;
static MPI_Win g_host_win = MPI_WIN_NULL;
/* Ranks declared dead (cv_comm_mark_dead): nothing is sent to them. */
static unsigned char *g_dead;
static int g_size, g_rank;
/* This rank was declared dead by the master (it stalled longer than
 * --gather-timeout): it leaves (docs/dead-rank.md); *g_stop_flag is set. */
static int g_self_dead;
static volatile sig_atomic_t *g_stop_flag;
static double g_notice_probe_t;
/* The master's silence (a non-master rank): the last message from rank 0,
 * the frame states seen (armed from the second: frame 0 has the start-up
 * time), the bound (2 x --gather-timeout; 0: off). */
static double g_master_seen, g_master_timeout;
static int g_master_states;
/* The master's end with a dead rank: the live ranks expected to say bye. */
static int g_end_dead, g_end_expect;

static void release(pending_send *ps);

struct cv_mailbox {
  int src, tag;
  size_t cap;
  uint8_t *buf;
  MPI_Request req;
  int posted;
};

int cv_comm_init(int *argc, char ***argv, int *rank, int *size) {
  int provided = 0;
  if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) return -1;
  /* An MPI error (a dead peer) returns to the caller instead of ending the
   * job; the communicators split from this one inherit the handler. */
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  MPI_Comm_rank(MPI_COMM_WORLD, rank);
  MPI_Comm_size(MPI_COMM_WORLD, size);
  g_size = *size;
  g_rank = *rank;
  g_dead = calloc((size_t)(*size > 0 ? *size : 1), 1);
  return 0;
}

/* Receives the probed death notice st from the master and applies it;
 * non-zero when it is too long or cannot be received. */
static int receive_notice(const MPI_Status *st) {
  uint8_t b[16];
  int count = 0;
  MPI_Get_count(st, MPI_BYTE, &count);
  if (count > (int)sizeof b ||
      MPI_Recv(b, (int)sizeof b, MPI_BYTE, 0, CV_TAG_ALIVE, MPI_COMM_WORLD, MPI_STATUS_IGNORE) != MPI_SUCCESS)
    return -1;
  g_master_seen = MPI_Wtime();
  cv_comm_dead_notice(b, count);
  return 0;
}

/* Takes the master's death notices not taken by a mailbox (a render rank
 * has none for CV_TAG_ALIVE). */
static void take_notices(void) {
  /* a notice may still be on its way behind the quit state (another tag):
   * looked for during 0.2 s */
  const double t0 = MPI_Wtime();
  for (int i = 0; i < 1024 && MPI_Wtime() - t0 < 0.2;) {
    int flag = 0;
    MPI_Status st;
    if (MPI_Iprobe(0, CV_TAG_ALIVE, MPI_COMM_WORLD, &flag, &st) != MPI_SUCCESS) return;
    if (!flag) continue;
    i++;
    if (receive_notice(&st)) return;
  }
}

/* 1 when every member of the host group reaches this point within limit_s.
 * Freeing the shared window is collective: a member that missed a death
 * notice (a loaded host: it may come after the quit state) would wait there
 * for ever on the others that skipped it, or on the dead one.  A member
 * that does not come in time is taken as gone; the request is left. */
static int host_group_present(double limit_s) {
  MPI_Request req;
  if (MPI_Ibarrier(g_host, &req) != MPI_SUCCESS) return 0;
  const double t0 = MPI_Wtime();
  int done = 0;
  while (!done && MPI_Wtime() - t0 < limit_s) {
    if (MPI_Test(&req, &done, MPI_STATUS_IGNORE) != MPI_SUCCESS) return 0;
    if (!done) {
      struct timespec ts = {0, 1000000};
      nanosleep(&ts, NULL);
    }
  }
  return done;
}

/* Tells the master this rank leaves (a dead rank is known, so no
 * MPI_Finalize): waited for 1 s at most. */
static void say_bye(void) {
  static const uint8_t bye = 'B'; /* MPI may still hold it after a time out */
  MPI_Request rq;
  if (MPI_Isend(&bye, 1, MPI_BYTE, 0, CV_TAG_BYE, MPI_COMM_WORLD, &rq) != MPI_SUCCESS) return;
  int done = 0;
  const double t0 = MPI_Wtime();
  while (!done && MPI_Test(&rq, &done, MPI_STATUS_IGNORE) == MPI_SUCCESS && MPI_Wtime() - t0 < 1.0) {
  }
}

void cv_comm_end_job(int code) {
  if (g_rank != 0 || !g_end_dead) return;
  /* the live ranks' byes, 10 s at most */
  int byes = 0;
  const double t0 = MPI_Wtime();
  while (byes < g_end_expect && MPI_Wtime() - t0 < 10.0) {
    int flag = 0;
    MPI_Status st;
    uint8_t b;
    if (MPI_Iprobe(MPI_ANY_SOURCE, CV_TAG_BYE, MPI_COMM_WORLD, &flag, &st) != MPI_SUCCESS) break;
    if (!flag) {
      struct timespec ms = {0, 1000000};
      nanosleep(&ms, NULL);
      continue;
    }
    if (MPI_Recv(&b, 1, MPI_BYTE, st.MPI_SOURCE, CV_TAG_BYE, MPI_COMM_WORLD, MPI_STATUS_IGNORE) != MPI_SUCCESS) break;
    byes++;
  }
  fprintf(stderr, "cave run: master: ending the job (MPI_Abort, status %d) with a dead rank: mpirun would "
          "wait for it (a host it cannot reach); %d of %d live ranks had left\n", code, byes, g_end_expect);
  fflush(stderr);
  fflush(stdout);
  MPI_Abort(MPI_COMM_WORLD, code);
}

void cv_comm_finalize(void) {
  cv_comm_flush(2.0);
  take_notices();
  /* the shared-lighting window: freeing it is collective over its host
   * group, so not with a dead rank (left to the process's exit) */
  int host_gone = 0;
  if (g_host != MPI_COMM_NULL && cv_comm_dead_count() == 0 && !g_self_dead) {
    if (host_group_present(30.0)) {
      if (g_host_win != MPI_WIN_NULL) MPI_Win_free(&g_host_win);
      MPI_Comm_free(&g_host);
    } else {
      host_gone = 1;
      fprintf(stderr, "rank %d: a member of the shared-lighting host group did not reach the end "
              "within 30 s: taken as dead, the window left to the process's exit\n", g_rank);
    }
  }
  if (g_render != MPI_COMM_NULL && !g_barrier_abandoned) MPI_Comm_free(&g_render);
  free(g_in_render);
  g_in_render = NULL;
  if (g_lcd != MPI_COMM_NULL && !g_lcd_abandoned) MPI_Comm_free(&g_lcd);
  for (size_t i = 0; i < g_nsends; i++) {
    MPI_Cancel(&g_sends[i].req);
    MPI_Request_free(&g_sends[i].req);
    release(&g_sends[i]);
  }
  free(g_sends);
  g_sends = NULL;
  g_nsends = g_capsends = 0;
  const int dead = cv_comm_dead_count() > 0 || host_gone;
  g_end_dead = dead || g_lcd_abandoned;
  g_end_expect = 0;
  for (int r = 1; r < g_size; r++) g_end_expect += !g_dead[r];
  const int master_live = !g_dead[0];
  free(g_dead);
  g_dead = NULL;
  /* With a dead rank MPI_Finalize (a collective of the runtime) may never
   * return: leave without it.  The master ends the job (cv_comm_end_job)
   * once the live ranks said they leave. */
  if (dead || g_lcd_abandoned) {
    if (g_rank != 0 && master_live) say_bye();
    return;
  }
  MPI_Finalize();
}

double cv_comm_time(void) { return MPI_Wtime(); }

void cv_comm_abort(int code, const char *msg) {
  if (msg) {
    fprintf(stderr, "%s\n", msg);
    fflush(stderr);
  }
  MPI_Abort(MPI_COMM_WORLD, code);
}

void cv_comm_mark_dead(int rank) {
  if (g_dead && rank >= 0 && rank < g_size) g_dead[rank] = 1;
}

int cv_comm_dead_count(void) {
  int n = 0;
  for (int r = 0; g_dead && r < g_size; r++) n += g_dead[r];
  return n;
}

int cv_comm_dead_notice(const uint8_t *data, long len) {
  int32_t r;
  if (len != 1 + (long)sizeof r || data[0] != 'D') return 0;
  memcpy(&r, data + 1, sizeof r);
  if (r == g_rank && g_rank != 0) { /* about this rank: it ran again after a stall */
    if (!g_self_dead)
      fprintf(stderr, "cave run: rank %d: the master declared this rank dead (silent longer than "
                      "--gather-timeout): leaving\n", g_rank);
    g_self_dead = 1;
    cv_comm_mark_dead(0); /* the job is over for it: no MPI_Finalize, nothing more waited for */
    if (g_stop_flag) *g_stop_flag = 1;
    return 1;
  }
  cv_comm_mark_dead(r);
  return 1;
}

void cv_comm_set_stop_flag(volatile sig_atomic_t *flag) { g_stop_flag = flag; }

int cv_comm_declared_dead(void) { return g_self_dead; }

/* A rank without a mailbox for CV_TAG_ALIVE (a wall-eye): the master's
 * notices, looked for at most every 50 ms. */
static void probe_notices(void) {
  if (g_rank == 0 || g_self_dead) return;
  const double now = MPI_Wtime();
  if (now - g_notice_probe_t < 0.05) return;
  g_notice_probe_t = now;
  for (int i = 0; i < 64; i++) {
    int flag = 0;
    MPI_Status st;
    if (MPI_Iprobe(0, CV_TAG_ALIVE, MPI_COMM_WORLD, &flag, &st) != MPI_SUCCESS || !flag) return;
    if (receive_notice(&st)) return;
  }
}

static int send_to(const void *buf, size_t n, int dest, int tag);

void cv_comm_notify_dead(int rank) {
  uint8_t b[1 + sizeof(int32_t)];
  const int32_t r = rank;
  b[0] = 'D';
  memcpy(b + 1, &r, sizeof r);
  for (int d = 1; d < g_size; d++)
    if (!g_dead[d]) cv_comm_send(b, sizeof b, d, CV_TAG_ALIVE);
  /* and to it: a rank only stalled (SIGSTOP, a swapping host) reads it when
   * it runs again and leaves; to a dead one the send is forgotten */
  if (rank > 0 && rank < g_size) send_to(b, sizeof b, rank, CV_TAG_ALIVE);
}

static int is_dead(int rank) { return g_dead && rank >= 0 && rank < g_size && g_dead[rank]; }

int cv_comm_is_dead(int rank) { return is_dead(rank); }

int cv_comm_send(const void *buf, size_t n, int dest, int tag) {
  if (n > (size_t)INT32_MAX) return -1;
  if (is_dead(dest)) return 0; /* dropped: nobody reads it */
  return send_to(buf, n, dest, tag);
}

static int send_to(const void *buf, size_t n, int dest, int tag) {
  if (g_nsends == g_capsends) {
    size_t nc = g_capsends ? 2 * g_capsends : 64;
    pending_send *p = realloc(g_sends, nc * sizeof *p);
    if (!p) return -1;
    g_sends = p;
    g_capsends = nc;
  }
  void *copy = malloc(n ? n : 1);
  if (!copy) return -1;
  if (n) memcpy(copy, buf, n);
  pending_send *ps = &g_sends[g_nsends];
  if (MPI_Isend(copy, (int)n, MPI_BYTE, dest, tag, MPI_COMM_WORLD, &ps->req) != MPI_SUCCESS) {
    free(copy);
    return -1;
  }
  ps->copy = copy;
  ps->refs = NULL;
  ps->dest = dest;
  g_nsends++;
  return 0;
}

int cv_comm_send_multi(const void *buf, size_t n, const int *dests, int ndest, int tag) {
  if (ndest <= 0) return 0;
  if (n > (size_t)INT32_MAX) return -1;
  if (g_nsends + (size_t)ndest > g_capsends) {
    size_t nc = g_capsends ? g_capsends : 64;
    while (nc < g_nsends + (size_t)ndest) nc *= 2;
    pending_send *p = realloc(g_sends, nc * sizeof *p);
    if (!p) return -1;
    g_sends = p;
    g_capsends = nc;
  }
  void *copy = malloc(n ? n : 1);
  int *refs = malloc(sizeof *refs);
  if (!copy || !refs) {
    free(copy);
    free(refs);
    return -1;
  }
  if (n) memcpy(copy, buf, n);
  *refs = 0;
  for (int i = 0; i < ndest; i++) {
    pending_send *ps = &g_sends[g_nsends];
    if (is_dead(dests[i])) continue;
    if (MPI_Isend(copy, (int)n, MPI_BYTE, dests[i], tag, MPI_COMM_WORLD, &ps->req) != MPI_SUCCESS)
      continue;
    ps->copy = copy;
    ps->refs = refs;
    ps->dest = dests[i];
    (*refs)++;
    g_nsends++;
  }
  if (*refs == 0) {
    free(copy);
    free(refs);
    return -1;
  }
  return 0;
}

static void release(pending_send *ps) {
  if (!ps->refs) {
    free(ps->copy);
  } else if (--*ps->refs == 0) {
    free(ps->copy);
    free(ps->refs);
  }
}

void cv_comm_set_master_timeout(double s) { g_master_timeout = s; }

/* A non-master rank that has heard nothing from the master for
 * g_master_timeout (from frame 1 on) takes the job as over: the master's host
 * is unreachable (its link down) or the master stopped.  It leaves as a rank
 * declared dead does (docs/dead-rank.md, "Several hosts"). */
static void master_watch(void) {
  if (g_rank == 0 || g_master_timeout <= 0 || g_master_states < 2 || g_self_dead) return;
  const double silent = MPI_Wtime() - g_master_seen;
  if (silent <= g_master_timeout) return;
  /* this rank may only have been stopped itself: what the master sent
   * meanwhile is queued (a receive already posted sees its message at its
   * next take; the others wait unexpected) */
  int queued = 0;
  if (MPI_Iprobe(0, MPI_ANY_TAG, MPI_COMM_WORLD, &queued, MPI_STATUS_IGNORE) == MPI_SUCCESS && queued) {
    g_master_seen = MPI_Wtime();
    return;
  }
  char host[256];
  cv_comm_host(host, sizeof host);
  fprintf(stderr, "cave run: rank %d on %s: nothing from the master for %.1f s (2 x --gather-timeout): its "
          "host unreachable or the master stopped; leaving\n", g_rank, host, silent);
  g_self_dead = 1;
  cv_comm_mark_dead(0);
  if (g_stop_flag) *g_stop_flag = 1;
}

int cv_comm_progress(void) {
  probe_notices();
  master_watch();
  size_t k = 0;
  for (size_t i = 0; i < g_nsends; i++) {
    int done = 0;
    /* a send to a dead rank never completes: forgotten (its copy leaks:
     * MPI may still hold it) */
    if (is_dead(g_sends[i].dest)) continue;
    if (MPI_Test(&g_sends[i].req, &done, MPI_STATUS_IGNORE) != MPI_SUCCESS) done = 1;
    if (done)
      release(&g_sends[i]);
    else
      g_sends[k++] = g_sends[i];
  }
  g_nsends = k;
  return (int)k;
}

void cv_comm_flush(double timeout_s) {
  const double t0 = MPI_Wtime();
  while (cv_comm_progress() > 0 && MPI_Wtime() - t0 < timeout_s) {
  }
}

static int mailbox_post(cv_mailbox *m) {
  if (m->posted) return 0;
  if (MPI_Irecv(m->buf, (int)m->cap, MPI_BYTE, m->src < 0 ? MPI_ANY_SOURCE : m->src, m->tag,
                MPI_COMM_WORLD, &m->req) != MPI_SUCCESS)
    return -1;
  m->posted = 1;
  return 0;
}

cv_mailbox *cv_mailbox_open(int src, int tag, size_t cap) {
  if (cap > (size_t)INT32_MAX) return NULL;
  cv_mailbox *m = calloc(1, sizeof *m);
  if (!m) return NULL;
  m->src = src;
  m->tag = tag;
  m->cap = cap;
  m->buf = malloc(cap ? cap : 1);
  if (!m->buf || mailbox_post(m)) {
    free(m->buf);
    free(m);
    return NULL;
  }
  return m;
}

long cv_mailbox_take(cv_mailbox *m, const uint8_t **data, int *from) {
  if (!m->posted && mailbox_post(m)) return -1;
  int flag = 0;
  MPI_Status st;
  MPI_Test(&m->req, &flag, &st);
  if (!flag) return -1;
  m->posted = 0;
  int count = 0;
  MPI_Get_count(&st, MPI_BYTE, &count);
  if (data) *data = m->buf;
  if (from) *from = st.MPI_SOURCE;
  if (st.MPI_SOURCE == 0 && g_rank != 0) {
    g_master_seen = MPI_Wtime();
    g_master_states += m->tag == CV_TAG_STATE;
  }
  return count;
}

void cv_mailbox_close(cv_mailbox *m) {
  if (!m) return;
  if (m->posted) {
    MPI_Cancel(&m->req);
    /* A receive already matched with a large message whose sender died (or
     * left) in the middle of it can neither be cancelled nor complete: an
     * MPI_Wait here kept a master from exiting after a dead rank (seen,
     * docs/dead-rank.md).  Waited for 1 s at most, then left to MPI with its
     * buffer, which MPI may still write. */
    int done = 0;
    const double t0 = MPI_Wtime();
    while (!done && MPI_Test(&m->req, &done, MPI_STATUS_IGNORE) == MPI_SUCCESS && MPI_Wtime() - t0 < 1.0) {
    }
    if (!done) return;
  }
  free(m->buf);
  free(m);
}

void cv_comm_barrier(void) { MPI_Barrier(MPI_COMM_WORLD); }

int cv_comm_bcast_int(int v) {
  MPI_Bcast(&v, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return v;
}


int cv_comm_render_group(int render) {
  MPI_Comm c;
  if (MPI_Comm_split(MPI_COMM_WORLD, render ? 1 : MPI_UNDEFINED, 0, &c) != MPI_SUCCESS) return -1;
  g_render = c;
  if (c != MPI_COMM_NULL && (g_in_render = calloc((size_t)g_size, 1))) { /* its members' world ranks */
    MPI_Group wg, rg;
    int n = 0;
    MPI_Comm_group(MPI_COMM_WORLD, &wg);
    MPI_Comm_group(c, &rg);
    MPI_Group_size(rg, &n);
    int *a = malloc((size_t)(n > 0 ? n : 1) * sizeof *a), *b = malloc((size_t)(n > 0 ? n : 1) * sizeof *b);
    if (a && b) {
      for (int i = 0; i < n; i++) a[i] = i;
      if (MPI_Group_translate_ranks(rg, n, a, wg, b) == MPI_SUCCESS)
        for (int i = 0; i < n; i++)
          if (b[i] >= 0 && b[i] < g_size) g_in_render[b[i]] = 1;
    }
    free(a);
    free(b);
    MPI_Group_free(&rg);
    MPI_Group_free(&wg);
  }
  return 0;
}

/* A member of the swap barrier died (or this rank was declared dead): the
 * barrier would never complete; given up for good. */
static int barrier_dead(void) {
  if (g_barrier_abandoned) return 1;
  int dead = g_self_dead;
  for (int r = 0; !dead && g_in_render && g_dead && r < g_size; r++) dead = g_in_render[r] && g_dead[r];
  if (dead) g_barrier_abandoned = 1;
  return dead;
}

int cv_comm_render_barrier_start(void) {
  if (g_render == MPI_COMM_NULL || g_barrier != MPI_REQUEST_NULL || barrier_dead()) return -1;
  return MPI_Ibarrier(g_render, &g_barrier) == MPI_SUCCESS ? 0 : -1;
}

int cv_comm_render_barrier_test(void) {
  if (g_barrier == MPI_REQUEST_NULL || barrier_dead()) return 1;
  int done = 0;
  MPI_Test(&g_barrier, &done, MPI_STATUS_IGNORE);
  return done;
}

/* The master is the LAST rank of the LCD communicator: in-place
 * MPI_Iallreduce is Open MPI libnbc's binomial tree (reduce to rank 0, then
 * broadcast), where rank 0 adds ceil(log2 p) whole buffers and the last rank
 * none (its partners would be beyond p): there the master only sends its
 * buffer and receives the sum, whatever the number of gather ranks.  Callers
 * see the master as member 0 (*rank = (comm rank + 1) mod size). */
int cv_comm_lcd_group(int member, int *size, int *rank) {
  *size = 0;
  *rank = -1;
  int world = 0, wsize = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &world);
  MPI_Comm_size(MPI_COMM_WORLD, &wsize);
  MPI_Comm c;
  if (MPI_Comm_split(MPI_COMM_WORLD, member ? 1 : MPI_UNDEFINED, world == 0 ? wsize : world, &c) != MPI_SUCCESS)
    return -1;
  g_lcd = c;
  if (c != MPI_COMM_NULL) {
    int r = 0;
    MPI_Comm_size(c, size);
    MPI_Comm_rank(c, &r);
    *rank = (r + 1) % *size;
  }
  return 0;
}

int cv_comm_lcd_iallreduce(int64_t *buf, size_t n) {
  if (g_lcd == MPI_COMM_NULL || g_lcd_abandoned || g_lcd_req != MPI_REQUEST_NULL || n > (size_t)INT32_MAX) return -1;
  return MPI_Iallreduce(MPI_IN_PLACE, buf, (int)n, MPI_INT64_T, MPI_SUM, g_lcd, &g_lcd_req) ==
                 MPI_SUCCESS
             ? 0
             : -1;
}

int cv_comm_lcd_test(void) {
  if (g_lcd_req == MPI_REQUEST_NULL || g_lcd_abandoned) return 1;
  int done = 0;
  if (MPI_Test(&g_lcd_req, &done, MPI_STATUS_IGNORE) != MPI_SUCCESS) return 1;
  return done;
}

void cv_comm_lcd_abandon(void) {
  g_lcd_abandoned = 1;
  g_lcd_req = MPI_REQUEST_NULL; /* the request in flight is never completed */
}

void cv_comm_host(char *buf, size_t cap) {
  char name[MPI_MAX_PROCESSOR_NAME];
  int len = 0;
  if (MPI_Get_processor_name(name, &len) != MPI_SUCCESS) len = 0;
  name[len] = 0;
  snprintf(buf, cap, "%s", name);
}

int cv_comm_host_share(int color, int key, size_t bytes, cv_host_share *out) {
  memset(out, 0, sizeof *out);
  out->leader = -1;
  if (g_render == MPI_COMM_NULL || bytes > (size_t)INT64_MAX) return -1;
  MPI_Comm node = MPI_COMM_NULL, grp = MPI_COMM_NULL;
  if (MPI_Comm_split_type(g_render, MPI_COMM_TYPE_SHARED, g_rank, MPI_INFO_NULL, &node) != MPI_SUCCESS)
    return -1;
  /* ties of key keep the order in node (world rank order) */
  const int rc = MPI_Comm_split(node, color >= 0 ? color : MPI_UNDEFINED, key, &grp);
  MPI_Comm_free(&node);
  if (rc != MPI_SUCCESS) return -1;
  if (grp == MPI_COMM_NULL) return 0; /* no part in it */
  int me = 0, n = 0;
  MPI_Comm_rank(grp, &me);
  MPI_Comm_size(grp, &n);
  /* the leader's world rank, known to all */
  int leader = g_rank;
  MPI_Bcast(&leader, 1, MPI_INT, 0, grp);
  void *mine = NULL;
  MPI_Win win = MPI_WIN_NULL;
  if (MPI_Win_allocate_shared((MPI_Aint)(me == 0 ? bytes : 0), 64, MPI_INFO_NULL, grp, &mine, &win) !=
      MPI_SUCCESS) {
    MPI_Comm_free(&grp);
    return -1;
  }
  MPI_Aint size = 0;
  int disp = 0;
  void *base = NULL;
  if (MPI_Win_shared_query(win, 0, &size, &disp, &base) != MPI_SUCCESS || (size_t)size < bytes || !base) {
    MPI_Win_free(&win);
    MPI_Comm_free(&grp);
    return -1;
  }
  /* the leader clears the segment before anyone reads it */
  if (me == 0) memset(base, 0, bytes);
  MPI_Barrier(grp);
  g_host = grp;
  g_host_win = win;
  out->base = base;
  out->bytes = (size_t)size;
  out->members = n;
  out->index = me;
  out->leader = leader;
  return 0;
}
