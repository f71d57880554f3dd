/* LCD round ownership with dead gather ranks: every round has exactly one
 * live owner, live contributors keep their own rounds, a dead one's rounds
 * are spread evenly over the live ones. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "service/lcdshare.h"
#include "test_service.h"

static void test_no_dead(void **state) {
  (void)state;
  for (uint32_t r = 0; r < 100; r++) assert_int_equal(cv_lcd_round_owner(r, 12, 10, 0), (int)(r % 12));
  assert_int_equal(cv_lcd_round_owner(5, 0, 0, 0), -1);
  /* bits past the contributors (gather ranks that do not exist) change nothing */
  assert_int_equal(cv_lcd_round_owner(11, 12, 10, ~0ull << 2), 11);
}

/* 10 wall-eyes (0-9) and 2 gather ranks (10, 11); gather rank 1 (= 11) dead. */
static void test_one_dead(void **state) {
  (void)state;
  const uint64_t dead = 2;
  assert_true(cv_lcd_contributor_dead(11, 10, dead) && !cv_lcd_contributor_dead(10, 10, dead));
  int share[12] = {0};
  for (uint32_t r = 0; r < 12u * 11u * 7u; r++) {
    const int o = cv_lcd_round_owner(r, 12, 10, dead);
    assert_true(o >= 0 && o < 11);
    if (r % 12 != 11) assert_int_equal(o, (int)(r % 12)); /* own rounds stay */
    share[o]++;
  }
  for (int c = 0; c < 11; c++) assert_int_equal(share[c], 7 * 11 + 7); /* own 77 + 7 of the dead's */
  assert_int_equal(share[11], 0);
}

/* No wall-eye contributors, 3 gather ranks: two dead, then all. */
static void test_gather_only(void **state) {
  (void)state;
  for (uint32_t r = 0; r < 300; r++) assert_int_equal(cv_lcd_round_owner(r, 3, 0, 5), 1);
  for (uint32_t r = 0; r < 30; r++) assert_int_equal(cv_lcd_round_owner(r, 3, 0, 7), -1);
  /* the dead one's rounds alternate between the two live ones */
  assert_int_equal(cv_lcd_round_owner(2, 3, 0, 4), 0);
  assert_int_equal(cv_lcd_round_owner(5, 3, 0, 4), 1);
  assert_int_equal(cv_lcd_round_owner(8, 3, 0, 4), 0);
}

int run_lcdshare_tests(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_no_dead),
      cmocka_unit_test(test_one_dead),
      cmocka_unit_test(test_gather_only),
  };
  return cmocka_run_group_tests_name("lcdshare", tests, NULL, NULL);
}
