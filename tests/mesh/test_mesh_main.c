/* test_mesh: runs the cabin-generator and geometry-cleaning groups. */
int run_cabin_tests(void);
int run_clean_tests(void);

int main(void) {
  int fails = run_cabin_tests();
  fails += run_clean_tests();
  return fails ? 1 : 0;
}
