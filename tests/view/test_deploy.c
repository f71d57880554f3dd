/* Unit tests of the deployment plan (src/view/deploy.c): for the 2-host
 * sample config every render rank sits on its output's host, the master is
 * rank 0 on the first output's host (or --master-host), gather ranks are
 * spread round-robin over the CAVE's hosts or fill a farm's slots in order,
 * slot indices are unique per host and the hosts' rank counts sum to the
 * rank count; the --cores core lists; the farm parser's one-line errors
 * (file:line: what was expected); the rankfile/hostfile text. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/status.h"
#include "view/cave.h"
#include "view/deploy.h"

#define CAVES CV_SOURCE_DIR "/configs/caves"

static void load(const char *path, cv_cave *c) {
  cv_err err = {0};
  int st = cv_cave_load(path, c, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
}

/* Slots 0..n-1 on every host, each once; rank counts sum to n_ranks. */
static void check_slots(const cv_deploy *d) {
  int sum = 0;
  for (int h = 0; h < d->n_hosts; h++) {
    const int n = d->hosts[h].ranks;
    sum += n;
    int *seen = calloc((size_t)n, sizeof *seen);
    assert_non_null(seen);
    int count = 0;
    for (int r = 0; r < d->n_ranks; r++) {
      if (strcmp(d->ranks[r].host, d->hosts[h].name)) continue;
      assert_true(d->ranks[r].slot >= 0 && d->ranks[r].slot < n);
      assert_int_equal(seen[d->ranks[r].slot], 0);
      seen[d->ranks[r].slot] = 1;
      count++;
    }
    assert_int_equal(count, n);
    free(seen);
  }
  assert_int_equal(sum, d->n_ranks);
}

static void test_two_hosts_gather(void **state) {
  (void)state;
  static cv_cave c;
  load(CAVES "/cave5-2hosts.json", &c);
  assert_int_equal(c.n_outputs, 10);
  cv_deploy_opts o = {NULL, 3, NULL, 0};
  cv_deploy d;
  cv_err err = {0};
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_OK);
  assert_int_equal(d.n_ranks, 14);
  assert_int_equal(d.n_render, 10);
  assert_int_equal(d.n_gather, 3);
  assert_int_equal(d.ranks[0].role, CV_ROLE_MASTER);
  assert_string_equal(d.ranks[0].host, "cave1");
  assert_int_equal(d.ranks[0].slot, 0);
  /* Every wall-eye's rank on its output's host. */
  for (int w = 0; w < c.n_walls; w++)
    for (int e = 0; e < 2; e++) {
      const int r = cv_cave_walleye_rank(&c, w, e);
      assert_true(r >= 1 && r <= 10);
      assert_int_equal(d.ranks[r].role, CV_ROLE_RENDER);
      const cv_output *out = &c.outputs[d.ranks[r].output];
      assert_int_equal(out->wall, w);
      assert_string_equal(d.ranks[r].host, out->host);
    }
  /* Gather ranks round-robin over cave1, cave2. */
  assert_string_equal(d.ranks[11].host, "cave1");
  assert_string_equal(d.ranks[12].host, "cave2");
  assert_string_equal(d.ranks[13].host, "cave1");
  for (int r = 11; r < 14; r++) assert_int_equal(d.ranks[r].role, CV_ROLE_GATHER);
  assert_int_equal(d.n_hosts, 2);
  assert_string_equal(d.hosts[0].name, "cave1");
  assert_int_equal(d.hosts[0].ranks, 9);
  assert_int_equal(d.hosts[1].ranks, 5);
  check_slots(&d);
  /* Without --cores the core list is the slot index. */
  assert_string_equal(d.ranks[7].cores, "0");
  assert_string_equal(d.ranks[13].cores, "8");

  /* The text: one "rank K=host slot=S" line per rank, hostfile slots sum. */
  char *buf = NULL;
  size_t len = 0;
  FILE *f = open_memstream(&buf, &len);
  assert_non_null(f);
  assert_int_equal(cv_deploy_write_rankfile(&d, "x.json", f), CV_OK);
  fclose(f);
  assert_non_null(strstr(buf, "\nrank 0=cave1 slot=0  # master\n"));
  assert_non_null(strstr(buf, "\nrank 7=cave2 slot=0  # render floor L\n"));
  assert_non_null(strstr(buf, "\nrank 12=cave2 slot=4  # gather\n"));
  int lines = 0;
  for (const char *p = buf; (p = strstr(p, "\nrank ")); p++) lines++;
  assert_int_equal(lines, 14);
  free(buf);
  f = open_memstream(&buf, &len);
  assert_int_equal(cv_deploy_write_hostfile(&d, NULL, f), CV_OK);
  fclose(f);
  assert_non_null(strstr(buf, "\ncave1 slots=9\ncave2 slots=5\n"));
  free(buf);
  f = open_memstream(&buf, &len);
  assert_int_equal(cv_deploy_write_table(&d, f), CV_OK);
  fclose(f);
  assert_non_null(strstr(buf, "mpirun -np 14"));
  assert_non_null(strstr(buf, "render ceiling R"));
  free(buf);
  cv_deploy_free(&d);

  /* --master-host elsewhere: a third host, listed first. */
  o.master_host = "head";
  o.n_gather = 0;
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_OK);
  assert_int_equal(d.n_ranks, 11);
  assert_string_equal(d.ranks[0].host, "head");
  assert_string_equal(d.hosts[0].name, "head");
  assert_int_equal(d.ranks[1].slot, 0);
  check_slots(&d);
  cv_deploy_free(&d);
}

static void test_one_host_and_cores(void **state) {
  (void)state;
  static cv_cave c;
  load(CAVES "/cave5.json", &c);
  cv_deploy_opts o = {NULL, 2, NULL, 2};
  cv_deploy d;
  cv_err err = {0};
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_OK);
  assert_int_equal(d.n_ranks, 13);
  assert_int_equal(d.n_hosts, 1);
  assert_string_equal(d.hosts[0].name, "localhost");
  for (int r = 0; r < 13; r++) {
    assert_string_equal(d.ranks[r].host, "localhost");
    assert_int_equal(d.ranks[r].slot, r);
    char want[8];
    snprintf(want, sizeof want, "%d", r % 2); /* 13 ranks on 2 cores: shared */
    assert_string_equal(d.ranks[r].cores, want);
  }
  check_slots(&d);
  cv_deploy_free(&d);
  /* 11 ranks on 16 cores: ranges of 1-2 cores, covering 0..15 in order. */
  o.n_gather = 0;
  o.cores = 16;
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_OK);
  assert_string_equal(d.ranks[0].cores, "0");
  assert_string_equal(d.ranks[10].cores, "14-15");
  int next = 0;
  for (int r = 0; r < 11; r++) {
    int a = -1, b = -1;
    if (sscanf(d.ranks[r].cores, "%d-%d", &a, &b) == 1) b = a;
    assert_int_equal(a, next);
    assert_true(b >= a);
    next = b + 1;
  }
  assert_int_equal(next, 16);
  cv_deploy_free(&d);
}

static void test_farm(void **state) {
  (void)state;
  static cv_cave c;
  load(CAVES "/cave5-2hosts.json", &c);
  cv_farm farm;
  cv_err err = {0};
  const char *text = "# render farm\n\nfarm1 slots=2   # two cores\n  farm2\r\nfarm3 slots=3\n";
  assert_int_equal(cv_farm_parse(text, "farm.txt", &farm, &err), CV_OK);
  assert_int_equal(farm.n, 3);
  assert_int_equal(farm.total_slots, 6);
  assert_string_equal(farm.hosts[1].name, "farm2");
  assert_int_equal(farm.hosts[1].slots, 1);
  cv_deploy_opts o = {"cave1", 99, &farm, 0}; /* n_gather ignored with a farm */
  cv_deploy d;
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_OK);
  assert_int_equal(d.n_ranks, 17);
  const char *want[6] = {"farm1", "farm1", "farm2", "farm3", "farm3", "farm3"};
  for (int k = 0; k < 6; k++) {
    assert_int_equal(d.ranks[11 + k].role, CV_ROLE_GATHER);
    assert_string_equal(d.ranks[11 + k].host, want[k]);
  }
  assert_int_equal(d.ranks[16].slot, 2);
  assert_int_equal(d.n_hosts, 5);
  check_slots(&d);
  cv_deploy_free(&d);
  cv_farm_free(&farm);

  /* Malformed lines: file:line and what was expected. */
  static const struct {
    const char *text, *part;
    int st;
  } bad[] = {
      {"farm1\nfarm2 slots=x\n", "farm.txt:2: expected 'slots=N'", CV_ERR_FORMAT},
      {"farm1 slots=0\n", "farm.txt:1: expected 'slots=N'", CV_ERR_FORMAT},
      {"farm1 slots=2 extra\n", "farm.txt:1: expected 'host [slots=N]'", CV_ERR_FORMAT},
      {"a\nb\nfarm=1\n", "farm.txt:3: expected 'host [slots=N]'", CV_ERR_FORMAT},
      {"farm1 max_slots=2\n", "farm.txt:1: expected 'slots=N'", CV_ERR_FORMAT},
      {"# nothing\n\n", "farm.txt: no host", CV_ERR_EMPTY},
      {"", "farm.txt: no host", CV_ERR_EMPTY},
      {"a slots=99999\nb slots=99999\n", "farm.txt:2: more than", CV_ERR_RANGE},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    memset(&farm, 0, sizeof farm);
    cv_err_clear(&err);
    assert_int_equal(cv_farm_parse(bad[i].text, "farm.txt", &farm, &err), bad[i].st);
    if (!strstr(err.msg, bad[i].part)) fprintf(stderr, "'%s' lacks '%s'\n", err.msg, bad[i].part);
    assert_non_null(strstr(err.msg, bad[i].part));
    assert_null(strchr(err.msg, '\n'));
    assert_null(farm.hosts);
  }
  assert_int_equal(cv_farm_load(CV_TEST_TMP_DIR "/no/such/farm.txt", &farm, &err), CV_ERR_IO);
  assert_non_null(strstr(err.msg, "cannot open"));
}

static void test_bad_options(void **state) {
  (void)state;
  static cv_cave c;
  load(CAVES "/cave5.json", &c);
  cv_deploy d;
  cv_err err = {0};
  cv_deploy_opts o = {NULL, -1, NULL, 0};
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "gather"));
  o.n_gather = 0;
  o.master_host = "bad host";
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "master host"));
  o.master_host = NULL;
  o.n_gather = CV_DEPLOY_MAX_RANKS;
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_ERR_RANGE);
  o.n_gather = 0;
  snprintf(c.outputs[3].host, sizeof c.outputs[3].host, "a=b");
  assert_int_equal(cv_deploy_plan(&c, &o, &d, &err), CV_ERR_CONFIG);
  assert_non_null(strstr(err.msg, "outputs[3].host"));
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_two_hosts_gather),
      cmocka_unit_test(test_one_host_and_cores),
      cmocka_unit_test(test_farm),
      cmocka_unit_test(test_bad_options),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
