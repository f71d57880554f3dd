#!/usr/bin/env bash
# End-to-end tests of `cave cluster` (docs/deploy.md): the rankfile for the
# 2-host sample CAVE puts rank 0 (the master) and every wall-eye on its
# output's host, spreads --gather ranks over the hosts, numbers slots
# uniquely per host; --farm fills a farm's slots; the hostfile's slots sum to
# the rank count that `cave run --check --ranks N` accepts; bad input gives a
# one-line error (config problems: one line each), exit 2 for usage and 1
# for file problems, and leaves no file (not even a temporary) behind.
# Usage: test_deploy.sh CAVE WORKDIR SOURCE_DIR
set -uo pipefail
CAVE="$1"; WORK="$2"; SRC="$3"
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK" || exit 1
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
CFG2="$SRC/configs/caves/cave5-2hosts.json"
CFG1="$SRC/configs/caves/cave5.json"

"$CAVE" cluster --help >help.txt 2>&1 && grep -q "examples:" help.txt && grep -q -- "--farm" help.txt \
  && ok "--help" || bad "--help: $(cat help.txt)"
"$CAVE" --help | grep -q "cluster" && ok "listed in cave --help" || bad "not in cave --help"

# --- the 2-host rankfile ------------------------------------------------------
"$CAVE" cluster rankfile "$CFG2" --gather 3 -o rf.txt >table.txt 2>err.txt; rc=$?
[ $rc -eq 0 ] && [ ! -s err.txt ] && grep -q "ranks: 14 " table.txt && ok "rankfile written, table on stdout" \
  || bad "rankfile rc $rc: $(cat err.txt)"
python3 - "$CFG2" rf.txt table.txt <<'PY' && ok "rankfile: master on cave1, every wall-eye on its output's host, gather spread, slots unique" || bad "rankfile content: $(cat rf.txt)"
import json, re, sys
cfg = json.load(open(sys.argv[1]))
ranks = {}
for line in open(sys.argv[2]):
    if line.startswith("#") or not line.strip():
        continue
    m = re.match(r"rank (\d+)=(\S+) slot=(\d+)(  # .*)?$", line.rstrip("\n"))
    assert m, line
    ranks[int(m.group(1))] = (m.group(2), int(m.group(3)))
assert sorted(ranks) == list(range(14)), sorted(ranks)
assert ranks[0] == ("cave1", 0), ranks[0]
for i, o in enumerate(cfg["outputs"]):
    assert ranks[1 + i][0] == o["host"], (i, o, ranks[1 + i])
gather = [ranks[r][0] for r in (11, 12, 13)]
assert gather == ["cave1", "cave2", "cave1"], gather
per_host = {}
for r, (h, s) in ranks.items():
    per_host.setdefault(h, []).append(s)
for h, slots in per_host.items():
    assert sorted(slots) == list(range(len(slots))), (h, slots)
table = open(sys.argv[3]).read()
assert re.search(r"\n\s+8\s+render floor R\s+cave2\s+1\s+1\s+:0.0\s+0\n", table), table
print("hosts:", {h: len(s) for h, s in per_host.items()})
PY

# --- hostfile: slots sum to the rank count cave run --check accepts ----------
"$CAVE" bake default -o s.prt --bands 3 --rays 32 --bounces 1 --quiet >/dev/null 2>&1 || bad "bake"
"$CAVE" cluster hostfile "$CFG2" --gather 3 -o hf.txt >t2.txt 2>&1 || bad "hostfile: $(cat t2.txt)"
sum=$(awk '!/^#/ && NF { sub("slots=", "", $2); s += $2 } END { print s }' hf.txt)
n=$(sed -n 's/^ranks: \([0-9]*\) .*/\1/p' t2.txt)
[ "$sum" = 14 ] && [ "$n" = 14 ] && grep -qx "cave1 slots=9" hf.txt && grep -qx "cave2 slots=5" hf.txt \
  && ok "hostfile slots sum to $sum = the printed rank count" || bad "hostfile sum $sum, printed $n: $(cat hf.txt)"
"$CAVE" run --http off --check --ranks "$n" "$CFG2" --scene s.prt >chk.txt 2>&1 \
  && grep -q "rank 10: wall ceiling, right eye, host cave2" chk.txt && ok "cave run --check --ranks $n accepts the 2-host config" \
  || bad "check: $(cat chk.txt)"
"$CAVE" run --http off --check --ranks 11 "$CFG2" --scene s.prt --present window >chk.txt 2>&1 \
  && ok "--check --present window accepts the 2-host config (displays given)" || bad "check window: $(cat chk.txt)"
# Without -o the file goes to stdout and the table to stderr.
"$CAVE" cluster rankfile "$CFG1" >so.txt 2>se.txt && [ "$(grep -c '^rank ' so.txt)" = 11 ] \
  && grep -q "ranks: 11 " se.txt && grep -q "rank 10=localhost slot=10" so.txt \
  && ok "one-host rankfile on stdout, table on stderr" || bad "stdout: $(cat so.txt se.txt)"

# --- a farm for the gather ranks ----------------------------------------------
printf '# farm\nfarm1 slots=2\n\nfarm2   # one slot\n' > farm.txt
"$CAVE" cluster rankfile "$CFG2" --farm farm.txt --master-host head -o rff.txt >tf.txt 2>&1 \
  && grep -qx "rank 0=head slot=0  # master" rff.txt && grep -qx "rank 11=farm1 slot=0  # gather" rff.txt \
  && grep -qx "rank 12=farm1 slot=1  # gather" rff.txt && grep -qx "rank 13=farm2 slot=0  # gather" rff.txt \
  && grep -q "ranks: 14 " tf.txt && ok "--farm fills slots in order, --master-host" || bad "farm: $(cat rff.txt tf.txt)"
"$CAVE" cluster rankfile "$CFG1" --cores 2 --gather 1 -o rfc.txt >/dev/null 2>&1 \
  && grep -qx "rank 11=localhost slot=1  # gather" rfc.txt && ok "--cores 2 wraps slots onto 2 cores" || bad "cores: $(cat rfc.txt)"

# --- errors: one line, exit status, no file left -------------------------------
printf 'farm1\nfarm2 slots=two\n' > badfarm.txt
sed 's/"gpu": 1, "stereo"/"gpu": 99, "stereo"/; s/"name": "left"/"name": "front"/' "$CFG2" > badcfg.json
expect() { # expect RC PATTERN LINES -- args...
  local want="$1" pat="$2" lines="$3"; shift 4
  rm -f out.rf out.rf.tmp.*
  "$CAVE" cluster "$@" >o.txt 2>e.txt; local rc=$?
  local nl; nl=$(grep -c "" e.txt)
  if [ $rc -eq "$want" ] && grep -q -- "$pat" e.txt && [ "$nl" -eq "$lines" ] && [ ! -s o.txt ] \
     && [ -z "$(ls out.rf* 2>/dev/null)" ]; then
    ok "rc $rc, $nl line(s), no file: $(head -1 e.txt)"
  else
    bad "cave cluster $*: rc $rc (want $want), $nl lines (want $lines): $(cat e.txt o.txt; ls out.rf* 2>/dev/null)"
  fi
}
expect 2 "'nodes': expected rankfile or hostfile" 1 -- nodes "$CFG2" -o out.rf
expect 2 "expected rankfile or hostfile" 1 -- -o out.rf
expect 2 "rankfile: expected a CAVE config" 1 -- rankfile -o out.rf
expect 1 "missing.json: cannot" 1 -- rankfile "$WORK/missing.json" -o out.rf
expect 1 "outputs\[4\].gpu" 7 -- rankfile badcfg.json -o out.rf   # every problem (duplicate wall name, 2 outputs of the renamed wall, 4 GPUs), one line each
expect 1 "--farm: .*nofarm.txt: cannot open" 1 -- rankfile "$CFG2" --farm nofarm.txt -o out.rf
expect 1 "--farm: .*: cannot read: Is a directory" 1 -- rankfile "$CFG2" --farm "$WORK" -o out.rf
expect 1 "badfarm.txt:2: expected 'slots=N'" 1 -- rankfile "$CFG2" --farm badfarm.txt -o out.rf
expect 2 "--gather: expected a rank count" 1 -- rankfile "$CFG2" --gather -1 -o out.rf
expect 2 "--gather: expected a rank count" 1 -- hostfile "$CFG2" --gather many -o out.rf
expect 2 "--gather and --farm" 1 -- rankfile "$CFG2" --gather 2 --farm farm.txt -o out.rf
expect 2 "unknown option '--nodes'" 1 -- rankfile "$CFG2" --nodes 2 -o out.rf
expect 2 "master host" 1 -- rankfile "$CFG2" --master-host "a b" -o out.rf
expect 2 "-o: expected a value" 1 -- rankfile "$CFG2" -o
expect 1 "-o: .*nodir/x.rf" 1 -- rankfile "$CFG2" -o nodir/x.rf
# An existing file is replaced whole or kept: a failed run leaves the old one.
echo "old" > keep.rf
"$CAVE" cluster rankfile "$CFG2" --farm badfarm.txt -o keep.rf >/dev/null 2>&1
[ "$(cat keep.rf)" = old ] && [ -z "$(ls keep.rf.tmp.* 2>/dev/null)" ] && ok "a failed run keeps the old file" || bad "keep.rf changed"

echo "cave cluster: $pass passed, $fail failed"
[ $fail -eq 0 ]
