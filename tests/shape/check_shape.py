#!/usr/bin/env python3
"""The code's shape (issue 32): no function in src/ or cluster/ over 150
lines, no two files of src/ and cluster/ calling each other in a cycle (from
the symbols the built objects define and use, `nm`), and no cycle of
#include among the project's headers.  Prints every violation, one a line;
exit 1 when there is one.

usage: check_shape.py SOURCE_DIR BUILD_DIR [--max-lines N]"""
import collections, glob, os, re, subprocess, sys

def strip_c(src):
    """Comments, strings and character constants blanked (newlines kept)."""
    src = re.sub(r'/\*.*?\*/', lambda m: '\n' * m.group(0).count('\n'), src, flags=re.S)
    src = re.sub(r'//[^\n]*', '', src)
    src = re.sub(r'"(\\.|[^"\\\n])*"', '""', src)
    return re.sub(r"'(\\.|[^'\\\n])*'", "''", src)

def long_functions(path, max_lines):
    """(name, first line, lines) of each top-level function body over max_lines."""
    lines = strip_c(open(path, encoding='utf-8', errors='replace').read()).split('\n')
    out, depth, start = [], 0, None
    for i, l in enumerate(lines):
        for ch in l:
            if ch == '{':
                if depth == 0: start = i
                depth += 1
            elif ch == '}':
                depth -= 1
                if depth == 0 and start is not None:
                    sig, j = '', start
                    while j >= 0 and j > start - 6:
                        sig = lines[j] + ' ' + sig
                        if re.match(r'^[A-Za-z]', lines[j]): break
                        j -= 1
                    m = re.search(r'([A-Za-z_]\w*)\s*\(', sig)
                    n = i - start + 1
                    if m and '=' not in sig.split('(')[0] and n > max_lines:
                        out.append((m.group(1), start + 1, n))
                    start = None
    return out

def sccs(graph):
    """Strongly connected components with more than one node (Tarjan)."""
    idx, low, stack, on, res, counter = {}, {}, [], set(), [], [0]
    sys.setrecursionlimit(100000)
    def visit(v):
        idx[v] = low[v] = counter[0]; counter[0] += 1; stack.append(v); on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in idx:
                visit(w); low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], idx[w])
        if low[v] == idx[v]:
            comp = []
            while True:
                w = stack.pop(); on.discard(w); comp.append(w)
                if w == v: break
            if len(comp) > 1: res.append(sorted(comp))
    for v in sorted(graph):
        if v not in idx: visit(v)
    return res

def call_graph(build):
    """File -> files whose global symbols it uses, from the objects' symbols."""
    objs = [o for o in glob.glob(os.path.join(build, '**', '*.o'), recursive=True)
            if '.dir/' in o and ('/src/' in o or '/cluster/' in o) and '/tests/' not in o]
    defs, uses = {}, collections.defaultdict(set)
    for o in objs:
        f = o.split('.dir/', 1)[1][:-2]
        nm = subprocess.run(['nm', '-g', o], capture_output=True, text=True, check=True).stdout
        for l in nm.splitlines():
            p = l.split()
            if len(p) == 3 and p[1] in 'TDBRVWG': defs[p[2]] = f
            elif len(p) == 2 and p[0] == 'U': uses[f].add(p[1])
    g = collections.defaultdict(set)
    for f, syms in uses.items():
        for s in syms:
            if defs.get(s) not in (None, f): g[f].add(defs[s])
    return g, len(objs)

def include_graph(srcdir):
    """Header -> project headers it includes (paths relative to src/ or cluster/)."""
    g = {}
    for h in glob.glob(os.path.join(srcdir, 'src', '**', '*.h'), recursive=True) + \
             glob.glob(os.path.join(srcdir, 'cluster', '*.h')):
        rel = os.path.relpath(h, srcdir)
        inc = set()
        for m in re.finditer(r'^\s*#\s*include\s+"([^"]+)"', open(h, errors='replace').read(), re.M):
            for base in ('src', 'cluster', os.path.dirname(rel)):
                cand = os.path.normpath(os.path.join(base, m.group(1)))
                if os.path.exists(os.path.join(srcdir, cand)):
                    inc.add(cand); break
        g[rel] = inc
    return g

def main():
    args = sys.argv[1:]
    if len(args) < 2 or args[0] in ('-h', '--help'):
        print(__doc__); return 0 if args and args[0] in ('-h', '--help') else 2
    srcdir, build = args[0], args[1]
    max_lines = int(args[args.index('--max-lines') + 1]) if '--max-lines' in args else 150
    bad = 0
    files = sorted(glob.glob(os.path.join(srcdir, 'src', '**', '*.c'), recursive=True) +
                   glob.glob(os.path.join(srcdir, 'cluster', '*.c')))
    for f in files:
        for name, line, n in long_functions(f, max_lines):
            print('%s:%d: %s is %d lines (at most %d)' % (os.path.relpath(f, srcdir), line, name, n, max_lines))
            bad += 1
    g, nobj = call_graph(build)
    if nobj == 0:
        print('no object files under %s: build first' % build); return 1
    for comp in sccs(g):
        print('call cycle: %s' % ' <-> '.join(comp)); bad += 1
    for comp in sccs(include_graph(srcdir)):
        print('include cycle: %s' % ' <-> '.join(comp)); bad += 1
    print('code shape: %d files, %d objects, longest allowed %d lines: %d problem(s)' %
          (len(files), nobj, max_lines, bad))
    return 1 if bad else 0

if __name__ == '__main__':
    sys.exit(main())
