# Shared by test_cli.sh and test_inputs.sh (sourced): pass/fail counters and
# the expect_* checks.  The caller sets pass=0 fail=0.
ok() { echo "ok: $1"; pass=$((pass + 1)); }
bad() { echo "FAIL: $1"; fail=$((fail + 1)); }

# expect_error NAME PATTERN CMD...: a clean failure (exit 1 or 2, no signal),
# whose last stderr line matches PATTERN (grep regex); with EXPECT_ONE_LINE=1
# (the default) an exit 1 (a file error) prints exactly one line.
expect_error() {
  local name=$1 pat=$2
  shift 2
  "$@" >out.txt 2>err.txt
  local rc=$?
  if [ $rc -eq 0 ] || [ $rc -gt 2 ]; then
    bad "$name: exit status $rc (expected 1 or 2)"; cat err.txt; return
  fi
  if ! tail -n 1 err.txt | grep -q -- "$pat"; then
    bad "$name: last error line lacks '$pat'"; cat err.txt; return
  fi
  if [ "${EXPECT_ONE_LINE:-1}" = 1 ] && [ $rc -eq 1 ] && [ "$(wc -l <err.txt)" -ne 1 ]; then
    bad "$name: expected one error line, got $(wc -l <err.txt)"; cat err.txt; return
  fi
  ok "$name: $(tail -n 1 err.txt)"
}

expect_ok() {
  local name=$1
  shift
  if "$@" >out.txt 2>err.txt; then ok "$name"; else bad "$name: exit $?"; cat err.txt out.txt; fi
}
