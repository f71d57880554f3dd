/* `cave tracker --listen`: receives DTrack ASCII packets as the tracker
 * config says and prints the calibrated head (marker, eyes, gaze, yaw,
 * pitch, roll) in CAVE coordinates, to check a calibration. */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>


#include "cli/cli.h"
#include "service/tracker_calib.h"

#define COUNT_MAX (1 << 30)

static void help(FILE *f) {
  fprintf(f,
          "usage: cave tracker [tracker.json] --listen [--count N] [--seconds S] [--port P]\n\n"
          "Receives ART DTrack ASCII packets (unicast, or the config's multicast group) and\n"
          "prints, per packet with the head body, the calibrated pose in CAVE coordinates\n"
          "(metres): the marker, the left and right eyes, the gaze, and yaw/pitch/roll in\n"
          "degrees.  Malformed packets (NaN, truncated) and packets without the body are\n"
          "counted and reported; the last pose is held.  The config (docs/tracker.md) gives\n"
          "the units, the room-to-CAVE transform, the body id, the marker-to-eye offset and\n"
          "the interpupillary distance; without one: mm, identity, body 1, port 5000.\n\n"
          "  --listen        receive and print (the only mode)\n"
          "  --count N       stop after N poses, 1..%d (default: until interrupted)\n"
          "  --seconds S     stop after S > 0 seconds (default: until interrupted)\n"
          "  --port P        UDP port 0..65535 instead of the config's (0: any free port,\n"
          "                  printed)\n\n"
          "examples:\n"
          "  cave tracker configs/trackers/dtrack.json --listen\n"
          "  cave tracker configs/trackers/dtrack.json --listen --count 10 --port 5001\n",
          COUNT_MAX);
}

static volatile sig_atomic_t g_stop = 0;
static void on_signal(int sig) {
  (void)sig;
  g_stop = 1;
}

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* No "-0.0000" for values that round to zero. */
static double z(double v) { return fabs(v) < 5e-5 ? 0.0 : v; }

static void print_head(uint32_t frame, const cv_tracked_head *h) {
  printf("frame %u marker %.4f %.4f %.4f left %.4f %.4f %.4f right %.4f %.4f %.4f "
         "gaze %.4f %.4f %.4f yaw %.2f pitch %.2f roll %.2f\n",
         frame, z(h->marker[0]), z(h->marker[1]), z(h->marker[2]), z(h->eye[0][0]),
         z(h->eye[0][1]), z(h->eye[0][2]), z(h->eye[1][0]), z(h->eye[1][1]), z(h->eye[1][2]),
         z(h->gaze[0]), z(h->gaze[1]), z(h->gaze[2]), z(h->yaw_deg), z(h->pitch_deg),
         z(h->roll_deg));
}

int cmd_tracker(int argc, char **argv) {
  const char *cfg_path = NULL;
  int listen = 0, count = 0, port = -1;
  double seconds = 0;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (!strcmp(a, "--listen")) {
      listen = 1;
    } else if (!strcmp(a, "--count") || !strcmp(a, "--seconds") || !strcmp(a, "--port")) {
      if (!v) {
        cli_print_usage(help);
        return cli_fail("tracker", 2, "%s: missing value", a);
      }
      i++;
      if (!strcmp(a, "--count") && cli_parse_int(v, 1, COUNT_MAX, &count))
        return cli_fail("tracker", 2, "--count: expected a pose count 1..%d, got '%s'", COUNT_MAX, v);
      if (!strcmp(a, "--port") && cli_parse_int(v, 0, 65535, &port))
        return cli_fail("tracker", 2, "--port: expected a UDP port 0..65535, got '%s'", v);
      if (!strcmp(a, "--seconds") && (cli_parse_double(v, &seconds) || !(seconds > 0) || seconds > 1e9))
        return cli_fail("tracker", 2, "--seconds: expected seconds > 0 (up to 1e9), got '%s'", v);
    } else if (a[0] == '-' && a[1]) {
      cli_print_usage(help);
      return cli_fail("tracker", 2, "unknown option '%s'", a);
    } else if (!cfg_path) {
      cfg_path = a;
    } else {
      return cli_fail("tracker", 2, "more than one config ('%s' and '%s')", cfg_path, a);
    }
  }
  if (!listen) {
    cli_print_usage(help);
    return cli_fail("tracker", 2, "missing --listen");
  }
  cv_tracker_config c;
  cv_err err;
  cv_err_clear(&err);
  if (cfg_path) {
    if (cv_tracker_config_load(cfg_path, &c, &err)) return cli_fail("tracker", 1, "%s", err.msg);
  } else {
    cv_tracker_config_default(&c);
  }
  cv_dtrack_receiver *rx;
  if (cv_tracker_open(&c, port, &rx, &err)) return cli_fail("tracker", 1, "%s", err.msg);
  printf("listening on %s:%d%s, body %d, units %g m, ipd %.4f m\n",
         c.multicast[0] ? c.multicast : c.bind, cv_dtrack_receiver_port(rx),
         c.multicast[0] ? " (multicast)" : "", c.body_id, c.unit_m, c.ipd);
  fflush(stdout);
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);
  const double t0 = now_s();
  int got = 0, rc = 0;
  cv_tracker_stats prev = {0, 0, 0, -1}, st = prev;
  while (!g_stop && (count == 0 || got < count) && (seconds == 0 || now_s() - t0 < seconds)) {
    cv_dtrack_frame f;
    int r = cv_dtrack_receiver_poll_frame(rx, now_s(), NULL, &f, &st);
    if (r < 0) {
      rc = cli_fail("tracker", 1, "receive failed on port %d", cv_dtrack_receiver_port(rx));
      break;
    }
    if (st.malformed > prev.malformed || st.no_body > prev.no_body) {
      fprintf(stderr,
              "warning: %llu malformed packet(s), %llu without a tracked body %d so far; "
              "holding the last pose\n",
              (unsigned long long)st.malformed, (unsigned long long)st.no_body, c.body_id);
    }
    prev = st;
    if (r == 1) {
      cv_tracked_head h;
      if (cv_tracker_head(&c, &f, &h) == CV_OK) {
        print_head(f.frame, &h);
        got++;
      }
      fflush(stdout);
    } else {
      struct timespec ts = {0, 2000000};
      nanosleep(&ts, NULL);
    }
  }
  printf("%d poses, %llu packets, %llu malformed, %llu without body %d\n", got,
         (unsigned long long)st.packets, (unsigned long long)st.malformed,
         (unsigned long long)st.no_body, c.body_id);
  cv_dtrack_receiver_close(rx);
  return rc;
}
