/* The cluster's message layer.  comm.c is the only file that includes
 * mpi.h: every MPI call of the service goes through these functions, so the
 * roles read as "send this, poll that".
 *
 * Why point-to-point with polling instead of collectives: a frame must not
 * wait for a late or stopped rank longer than the configured timeout
 * (issue 6, faults).  MPI collectives (bcast trees, allreduce) stall every
 * participant behind the slowest one, and Open MPI 4 has no fault tolerance.
 * So the master sends the frame state to each rank (eager, small), and
 * collects reports, patch images and LCD rounds from per-source mailboxes
 * that it polls until a deadline; what is late is skipped and counted, and
 * discarded when it arrives later (messages carry their frame number).
 * The one collective on the data path is the LCD sum of the master and the
 * gather-only ranks (cluster/lcdreduce.c): a non-blocking MPI_Iallreduce
 * (MPI_SUM, MPI_INT64_T) of fixed-point images on their own communicator,
 * which the master only tests (MPI_Test), so a late gather rank delays the
 * sum, never a frame.  The render ranks' idle-thread rounds still come
 * point-to-point (the render ranks must never wait in a collective).  Both
 * are integer sums: the same bits in any order and for any rank count. */
#ifndef CV_CLUSTER_COMM_H
#define CV_CLUSTER_COMM_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

enum {
  CV_TAG_STATE = 1,   /* master -> all: packed cv_frame_state */
  CV_TAG_REPORT = 2,  /* wall-eye -> master: packed cv_walleye_report */
  CV_TAG_PATCH = 3,   /* wall-eye -> master: frame + patch image of its wall */
  CV_TAG_CORR = 4,    /* master -> wall-eye: frame + patch correction of its wall */
  CV_TAG_LCD = 5,     /* contributor -> master: LCD round (key, round, fixed point) */
  CV_TAG_LCDIMG = 6,  /* master -> wall-eyes: current LCD image */
  CV_TAG_READY = 7,   /* every rank -> master at start: set-up done or failed */
  CV_TAG_IMAGE = 8,   /* left-eye wall-eye -> master: display image of a written frame */
  CV_TAG_PING = 9,    /* master -> render rank: clock probe (t0 of the master) */
  CV_TAG_PONG = 10,   /* render rank -> master: t0 echoed, t1 (received), t2 (sent) */
  CV_TAG_STOPREQ = 11, /* render rank -> master: its window was closed / Escape / X lost */
  CV_TAG_SWAPREADY = 12, /* render rank -> master: frame drawn and finished (u32 frame) */
  CV_TAG_GO = 13,       /* master -> render rank: swap frame at this time of the rank's clock */
  CV_TAG_PREVIEW = 14,  /* left-eye render rank -> master: 8-bit image of a desktop preview frame */
  CV_TAG_ALIVE = 15,    /* gather rank -> master: heartbeat (u32 count), every 0.25 s;
                           master -> all: 'D' + int32 rank: that rank is dead */
  CV_TAG_LIGHT = 16,    /* render rank -> master: its lighting step (cv_light_msg, lightshare.h) */
  CV_TAG_BYE = 17       /* rank -> master at its end when a rank is dead (no MPI_Finalize) */
};

/* MPI_Init_thread, and MPI_ERRORS_RETURN on MPI_COMM_WORLD: an error with a
 * dead peer returns (-1 from these calls) instead of ending the job. */
int cv_comm_init(int *argc, char ***argv, int *rank, int *size);
void cv_comm_finalize(void);
/* The master, after cv_comm_finalize, when a rank was dead: waits (10 s at
 * most) for every live rank's bye, then ends the job with MPI_Abort(code), so
 * that mpirun does not wait for ranks on a host it cannot reach (a link
 * down).  Returns when no rank was dead, or on other ranks. */
void cv_comm_end_job(int code);
/* A non-master rank leaves when it heard nothing from the master for s
 * seconds from frame 1 on (0: never); run.c sets 2 x --gather-timeout. */
void cv_comm_set_master_timeout(double s);
double cv_comm_time(void);
/* Ends the whole job now (MPI_Abort) after printing msg on stderr. */
void cv_comm_abort(int code, const char *msg);

/* Sends a copy of buf (n bytes) to dest with tag; returns at once.  The copy
 * is freed when MPI reports the send complete (cv_comm_progress).  0 on
 * success, -1 out of memory or MPI error. */
int cv_comm_send(const void *buf, size_t n, int dest, int tag);
/* Sends one copy of buf to each of the n ranks in dests (one buffer,
 * freed after the last send completes).  0 on success. */
int cv_comm_send_multi(const void *buf, size_t n, const int *dests, int ndest, int tag);
/* Completes finished sends, frees their copies; returns the number still
 * pending.  Call it from every polling loop. */
int cv_comm_progress(void);
/* Waits up to timeout_s for pending sends (at exit). */
void cv_comm_flush(double timeout_s);

/* A mailbox: one posted receive of up to cap bytes from src (MPI rank, or
 * -1 for any source) with tag, re-posted after each message is taken. */
typedef struct cv_mailbox cv_mailbox;
cv_mailbox *cv_mailbox_open(int src, int tag, size_t cap);
/* If a message has arrived: returns its size (>= 0) and copies nothing:
 * *data points into the mailbox (valid until the next take) and *from gets
 * the sender.  Returns -1 when nothing has arrived.  The receive is
 * re-posted by the next cv_mailbox_take call. */
long cv_mailbox_take(cv_mailbox *m, const uint8_t **data, int *from);
void cv_mailbox_close(cv_mailbox *m);

/* MPI_Barrier (the optional swap lock). */
void cv_comm_barrier(void);
/* Rank 0's v on every rank (MPI_Bcast, collective; start-up only). */
int cv_comm_bcast_int(int v);

/* The render ranks' communicator (the swap lock): every rank calls it once
 * after init, collectively, with render = 1 on the ranks that render. */
int cv_comm_render_group(int render);
/* Starts a non-blocking barrier among the render ranks (MPI_Ibarrier on
 * their communicator); cv_comm_render_barrier_test polls it: 1 done, 0 not
 * yet.  One barrier at a time per rank.  Once a render rank is known dead
 * (or this one was declared dead) the barrier is given up: start fails,
 * test says done (docs/dead-rank.md). */
int cv_comm_render_barrier_start(void);
int cv_comm_render_barrier_test(void);
/* The LCD reduction's communicator (the master and the gather-only ranks,
 * cluster/lcdreduce.c): every rank calls it once after init, collectively,
 * with member = 1 on those ranks.  *size / *rank: this rank's place in it
 * (0 / -1 when not a member; the master is member 0, placed last in the
 * communicator, a leaf of the sum's tree: comm.c). */
int cv_comm_lcd_group(int member, int *size, int *rank);
/* Starts an in-place non-blocking sum of n int64 words over that
 * communicator (MPI_Iallreduce, MPI_SUM); buf must stay untouched until
 * cv_comm_lcd_test says done.  One at a time per rank.  0 on success. */
int cv_comm_lcd_iallreduce(int64_t *buf, size_t n);
/* Polls it (MPI_Test): 1 done (or none in flight), 0 not yet. */
int cv_comm_lcd_test(void);
/* Gives the LCD sum up for good (a member died): the sum in flight is never
 * waited on again, no new one starts (cv_comm_lcd_iallreduce fails) and
 * cv_comm_lcd_test says done. */
void cv_comm_lcd_abandon(void);
/* Marks a rank dead: sends to it are dropped (those in flight forgotten);
 * with a dead rank cv_comm_finalize skips MPI_Finalize. */
void cv_comm_mark_dead(int rank);
int cv_comm_dead_count(void);
/* Master: tells every live rank that rank is dead ('D' + int32 rank, tag
 * CV_TAG_ALIVE), so that none waits for it in MPI_Finalize. */
void cv_comm_notify_dead(int rank);
/* A rank: marks the rank of such a notice dead; 1 if data is one, else 0.
 * A notice naming this rank itself (it was stalled, not dead) sets
 * cv_comm_declared_dead and the stop flag: the rank leaves.  cv_comm_progress
 * looks for notices no mailbox takes (at most every 50 ms); cv_comm_finalize
 * takes the rest. */
int cv_comm_dead_notice(const uint8_t *data, long len);
/* The flag a notice naming this rank sets (the SIGINT/SIGTERM flag). */
void cv_comm_set_stop_flag(volatile sig_atomic_t *flag);
/* 1 once the master has declared this rank dead. */
int cv_comm_declared_dead(void);
/* 1 when rank was marked dead (cv_comm_mark_dead or a master's notice). */
int cv_comm_is_dead(int rank);

/* Shared lighting (cluster/lightshare.c): one shared-memory segment per
 * host for the render ranks of that host that pass the same color (>= 0:
 * the same scene and GL).  Collective over the render ranks (every one
 * calls it, color -1 on a rank that takes no part):
 * MPI_Comm_split_type(MPI_COMM_TYPE_SHARED) of the render communicator,
 * MPI_Comm_split of that by color (ordered by key, then world rank: the
 * first is the leader), and
 * MPI_Win_allocate_shared of `bytes` by the group's first rank (the
 * leader), 0 by the others, who map the leader's segment
 * (MPI_Win_shared_query).  0 on success; then base (NULL when not a member),
 * members (1: alone on its host), index (0 = the leader) and leader (its
 * world rank).  The segment is freed by cv_comm_finalize. */
typedef struct cv_host_share {
  void *base;
  size_t bytes;
  int members, index, leader;
} cv_host_share;
int cv_comm_host_share(int color, int key, size_t bytes, cv_host_share *out);

/* Name of this rank's host (MPI_Get_processor_name). */
void cv_comm_host(char *buf, size_t cap);

#endif
