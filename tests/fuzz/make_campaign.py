#!/usr/bin/env python3
"""Writes the hostile inputs of the campaign (docs/fuzzing.md) into OUT/<kind>/:
prt (header lies, bad records with a valid hash, truncations), scene, cave and
display JSON (syntax errors, empty, NaN, 1e999, mangled keys, truncations).
Deterministic (no randomness).  Usage: make_campaign.py SOURCE_ROOT OUT"""
import os, struct, sys

root, out = sys.argv[1], sys.argv[2]

def put(kind, name, data):
    os.makedirs(os.path.join(out, kind), exist_ok=True)
    with open(os.path.join(out, kind, name), 'wb') as f:
        f.write(data)

def fnv(b):
    h = 0xcbf29ce484222325
    for c in b:
        h = ((h ^ c) * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return h

# --- .prt: from the seed with indirect transfer (7 vertices, 3 triangles, 2 bands)
prt = open(os.path.join(root, 'tests/fuzz/prt/tiny_indirect.prt'), 'rb').read()
nv, nt, nm = struct.unpack('<3Q', prt[24:48])
bands = struct.unpack('<I', prt[16:20])[0]
for field, off, size in (('nv', 24, 8), ('nt', 32, 8), ('nm', 40, 8), ('bands', 16, 4)):
    for v in (0, 1, 2**20, 2**30, 2**32, 2**40, 2**63):
        if size == 4 and v >= 2**32:
            continue
        b = bytearray(prt)
        b[off:off + size] = struct.pack('<Q' if size == 8 else '<I', v)
        put('prt', 'header_%s_%d.prt' % (field, v), bytes(b))
nc = bands * bands
pos, nrm, alb = 128, 128 + 12 * nv, 128 + 24 * nv
td = 128 + 36 * nv + 16 * nt + 80 * nm
records = {
    'nan_normal': (nrm + 4, float('nan')), 'short_normal': (nrm, 0.5),
    'neg_albedo': (alb + 4, -0.25), 'albedo_2': (alb, 2.0), 'nan_albedo': (alb + 8, float('nan')),
    'inf_position': (pos, float('inf')), 'nan_transfer': (td + 8, float('nan')),
}
for name, (off, v) in records.items():
    b = bytearray(prt)
    b[off:off + 4] = struct.pack('<f', v)
    b[56:64] = struct.pack('<Q', fnv(bytes(b[128:])))
    put('prt', 'record_%s.prt' % name, bytes(b))
for cut in (0, 7, 64, 127, 128, 200, len(prt) - 1):
    put('prt', 'cut_%d.prt' % cut, prt[:cut])

# --- JSON: each shipped config, mutated
def json_mutations(text):
    yield 'empty', b''
    yield 'spaces', b'  \n\t\n'
    for k in (1, len(text) // 3, len(text) // 2, len(text) - 2):
        yield 'cut_%d' % k, text[:k]
    i = text.find(b'[')
    if i >= 0:
        yield 'nan', text[:i + 1] + b'NaN, ' + text[i + 1:]
        yield 'inf', text[:i + 1] + b'-Infinity, ' + text[i + 1:]
        yield 'huge_number', text[:i + 1] + b'1e999, ' + text[i + 1:]
    j = text.find(b'"', 1)
    if j >= 0:
        yield 'ctrl_key', text[:j + 1] + b'\x01\x7f\xff' + text[j + 1:]
    yield 'trailing_comma', text.rstrip().rstrip(b'}') + b', }'
    yield 'no_close', text.rstrip().rstrip(b'}')
    yield 'binary', bytes(range(256))
    yield 'array_root', b'[1, 2, 3]'
for kind, folder in (('scene', 'configs/scenes'), ('cave', 'configs/caves'),
                     ('display', 'configs/displays')):
    for fn in sorted(os.listdir(os.path.join(root, folder))):
        if not fn.endswith('.json'):
            continue
        text = open(os.path.join(root, folder, fn), 'rb').read()
        for name, data in json_mutations(text):
            put(kind, '%s_%s.json' % (fn[:-5], name), data)
