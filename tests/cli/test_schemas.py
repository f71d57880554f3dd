#!/usr/bin/env python3
"""JSON Schemas of the config formats (configs/schema/, docs/*.md): every
shipped config validates against its schema, and the C parsers reject what
the schemas reject (and accept the valid samples).  Uses python3-jsonschema
(Debian; installed by cluster/setup.sh).

Usage: test_schemas.py CAVE SOURCE_ROOT WORKDIR MAKE_TEST_INPUTS"""
import glob, json, os, shutil, subprocess, sys

import jsonschema

CAVE, ROOT, WORK, MK = sys.argv[1:5]
shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(WORK)
os.chdir(WORK)
passed = failed = 0


def ok(msg):
    global passed
    passed += 1
    print("ok:", msg)


def bad(msg):
    global failed
    failed += 1
    print("FAIL:", msg)


def run(args, timeout=120):
    p = subprocess.run([CAVE] + args, capture_output=True, text=True, errors="replace", timeout=timeout)
    return p.returncode, p.stdout + p.stderr


HAVE_RUN = any(l.startswith("  run ") for l in run(["--help"])[1].splitlines())
subprocess.run([MK, "."], check=True, capture_output=True)  # white.exr for cave compensate
rc, out = run(["bake", "default", "-o", "s.prt", "--bands", "2", "--rays", "4", "--bounces", "0", "--quiet"])
assert rc == 0, out


def c_check(kind, path):
    """(accepted, output) of the C parser for one config file."""
    if kind == "scene":
        rc, out = run(["materials", path])
        if rc == 0 and "lcd" in json.load(open(path)):  # the lcd block is read by cave lcd
            rc, out = run(["lcd", path, "--prt", "s.prt", "--eye", "-0.37,1.1,0.3", "--env-constant",
                           "1,1,1", "--spp", "1", "--size", "8x6", "-o", "lcdcheck.exr"])
    elif kind == "tracker":
        rc, out = run(["tracker", path, "--listen", "--seconds", "0.05", "--port", "0"])
    elif kind == "display":
        rc, out = run(["compensate", "--display", path, "--image", "white.exr", "-o", "comp.exr", "--quiet"])
    elif kind == "cave":
        rc, out = run(["run", "--check", "--ranks", "64", path, "--scene", "s.prt"])
    else:
        rc, out = run(["run", "--check", "--ranks", "11", ROOT + "/configs/caves/cave5.json",
                       "--scene", "s.prt", "--drive", path])
    return rc == 0, out


R01 = "/usr/share/assimp/models/OBJ/regr01.obj"
SAMPLES = {
    "scene": {
        "valid": [
            {"mesh": {"path": R01, "units": "cm", "up": "z", "transform": {"rotate_deg": [0, 90, 0]}},
             "materials": [{"name": "*", "albedo": [0.5, 0.5, 0.5]}]},
            {"lighting": {"env": "forest.exr", "illuminance": "auto"}, "prt": {"bands": "auto"}},
            {"lighting": {"env": "forest.exr", "scale": 10000, "absolute": True}},
            {"mesh": {"source": "cabin", "tess": 1}, "lighting": {"sky": {"turbidity": 4}},
             "lcd": {"resolution": [200, 150], "cr_min": 3, "age": 60}},
            {"mesh": {"source": "cabin", "tess": 1},
             "lcd": {"panels": [{"name": "centre"}, {"name": "cluster", "content_luminance": 300,
                                 "corners": [[-0.46, 0.6813, -0.9772], [-0.28, 0.6813, -0.9772], [-0.46, 0.7596, -0.9937]]}]}},
        ],
        "invalid": [
            {"mesh": {"source": "cabin", "units": "cm"}},
            {"mesh": {"path": "x.obj", "units": "furlong"}},
            {"mesh": {"path": "x.obj", "units": -1}},
            {"mesh": {"path": "x.obj", "up": "x"}},
            {"mesh": {"path": "x.obj", "transform": {"scale": 0}}},
            {"mesh": {"path": "x.obj", "transform": {"rotate": [0, 0, 0]}}},
            {"materials": [{"albedo": [0.5, 0.5, 0.5]}]},
            {"materials": [{"name": "a", "tag": "glass"}]},
            {"prt": {"bands": 9}},
            {"prt": {"rays": "many"}},
            {"lighting": {"env": "forest.exr", "scale": 2, "illuminance": 100}},
            {"lighting": {"sky": {}, "illuminance": 100}},
            {"lighting": {"env": "forest.exr", "sky": {}}},
            {"lighting": {"env": "forest.exr", "illuminance": "bright"}},
            {"lighting": {"env": "forest.exr", "illuminance": 100, "absolute": True}},
            {"lighting": {"sky": {}, "absolute": True}},
            {"lighting": {"env": "forest.exr", "absolute": 1}},
            {"colour": 1},
            {"lcd": {"resolution": [400, 0]}},
            {"lcd": {"cr_min": 0.5}},
            {"lcd": {"panels": []}},
            {"lcd": {"panels": [{"corners": [[0, 0.6, -0.95], [0.2, 0.6, -0.95], [0, 0.7, -0.97]]}]}},
            {"lcd": {"panels": [{"name": "a b"}]}},
            {"lcd": {"panels": [{"name": "a", "corners": [[0, 0.6, -0.95], [0.2, 0.6, -0.95]]}]}},
            {"lcd": {"panels": [{"name": "a", "glare": 1}]}},
        ],
    },
    "tracker": {
        "valid": [{"units": 0.001, "body_id": 2, "udp": {"bind": "127.0.0.1"}},
                  {"units": "cm", "eye_offset": [0, -0.05, 0.1], "ipd": 0.06}],
        "invalid": [{"units": "furlong"}, {"ipd": 0.2}, {"udp": {"port": 0}}, {"body_id": 1.5},
                    {"eye_offset": [0, 0]}, {"room_to_cave": {"rotate": [0, 0, 0]}}, {"extra": 1}],
    },
    "drive": {
        "valid": [{"maps": ["forest.exr"], "illuminance": "auto", "keyframes": [{"t": 0}]},
                  {"maps": ["forest.exr"], "scale": 10000, "absolute": True, "keyframes": [{"t": 0}]},
                  {"sky": True, "keyframes": [{"t": 0, "turbidity": 3}]}],
        "invalid": [
            {"maps": ["forest.exr"], "scale": 2, "illuminance": 5, "keyframes": [{"t": 0}]},
            {"sky": True, "maps": ["forest.exr"], "keyframes": [{"t": 0}]},
            {"maps": ["forest.exr"], "keyframes": []},
            {"maps": ["forest.exr"], "keyframes": [{"t": 0, "turbidity": 3}]},
            {"sky": True, "keyframes": [{"t": 0, "weights": [1]}]},
            {"maps": ["forest.exr"], "keyframes": [{"t": 0}], "speed": 1},
            {"sky": True, "illuminance": "auto", "keyframes": [{"t": 0}]},
            {"sky": True, "absolute": True, "keyframes": [{"t": 0}]},
            {"maps": ["forest.exr"], "illuminance": 5, "absolute": True, "keyframes": [{"t": 0}]},
            {"maps": ["forest.exr"], "absolute": "yes", "keyframes": [{"t": 0}]},
        ],
    },
}
WALL = {"name": "f", "pa": [-1, 0, -1], "pb": [1, 0, -1], "pc": [-1, 2, -1], "res": [64, 64]}
SAMPLES["cave"] = {
    "valid": [{"walls": [WALL]},
              {"walls": [WALL], "eye_separation": 0.06, "screens": {"reflectance": 0.7},
               "outputs": [{"wall": "f", "eye": "left", "gpu": "software"},
                           {"wall": "f", "eye": "right", "gpu": "software"}]}],
    "invalid": [
        {"walls": []},
        {"walls": [{k: v for k, v in WALL.items() if k != "res"}]},
        {"walls": [WALL], "eye_separation": 0.5},
        {"walls": [WALL], "supersample": 3},
        {"walls": [WALL], "rate": 0},
        {"walls": [WALL], "screens": {"reflectance": 1}},
        {"walls": [WALL], "outputs": [{"wall": "f", "eye": "both", "stereo": "quad"}]},
        {"walls": [WALL], "outputs": [{"wall": "f", "eye": "middle", "gpu": "auto"}]},
        {"walls": [WALL], "outputs": [{"wall": "f", "gpu": "auto"}]},
        {"walls": [WALL], "colour": 1},
        {"walls": [WALL], "outputs": [{"wall": "f", "eye": "both", "gpu": "auto"}]},
    ],
}
PLANE = {"name": "a", "corners": [[-1, 0, -1], [1, 0, -1], [-1, 2, -1]], "patches": [2, 2],
         "reflectance": [0.5, 0.5, 0.5]}
SAMPLES["display"] = {
    "valid": [{"surfaces": [PLANE]},
              {"surfaces": [PLANE, {"name": "c", "type": "cylinder", "center": [0, 0, 0], "radius": 2,
                                    "angle_deg": [-30, 30], "height": [0, 2], "patches": [2, 2],
                                    "reflectance": [0.5, 0.5, 0.5], "refine": {"seams": "auto"}}],
               "environment": [0.01, 0.01, 0.01], "projectors": [{"position": [0, 1, 1]}]}],
    "invalid": [
        {"surfaces": []},
        {"surfaces": [dict(PLANE, patches=[0, 2])]},
        {"surfaces": [dict(PLANE, reflectance=[0.5, 0.5, 1.5])]},
        {"surfaces": [dict(PLANE, cosine_exponent=0)]},
        {"surfaces": [dict(PLANE, normal_tilt_deg=90)]},
        {"surfaces": [dict(PLANE, refine={"seams": ["middle"]})]},
        {"surfaces": [dict(PLANE, type="sphere")]},
        {"surfaces": [{"name": "d", "type": "dome", "center": [0, 0, 0], "radius": 2, "elevation_deg": [0, 100],
                       "azimuth_deg": [-30, 30], "patches": [2, 2], "reflectance": [0.5, 0.5, 0.5]}]},
        {"surfaces": [PLANE], "projectors": "real"},
        {"surfaces": [PLANE], "environment": [-1, 0, 0]},
        {"surfaces": [PLANE], "colour": 1},
    ],
}
# shipped displays: schema only (their compensation takes up to half a minute)
SHIPPED = {"scene": "scenes", "tracker": "trackers", "drive": "drives", "cave": "caves", "display": "displays"}

for kind, folder in SHIPPED.items():
    schema = json.load(open(f"{ROOT}/configs/schema/{kind}.schema.json"))
    jsonschema.Draft7Validator.check_schema(schema)
    v = jsonschema.Draft7Validator(schema)
    can_c = kind not in ("drive", "cave") or HAVE_RUN
    for f in sorted(glob.glob(f"{ROOT}/configs/{folder}/*.json")):
        errs = [e.message for e in v.iter_errors(json.load(open(f)))]
        name = os.path.relpath(f, ROOT)
        if errs:
            bad(f"{name} does not validate: {errs[0]}")
            continue
        if can_c and kind != "display":
            acc, out = c_check(kind, f)
            if not acc:
                bad(f"{name} validates but the C parser refuses it: {out.strip().splitlines()[-1]}")
                continue
        ok(f"{name} validates against {kind}.schema.json")
    for i, s in enumerate(SAMPLES[kind]["valid"]):
        path = f"{kind}_valid{i}.json"
        json.dump(s, open(path, "w"))
        errs = [e.message for e in v.iter_errors(s)]
        acc, out = c_check(kind, path) if can_c else (True, "")
        if errs or not acc:
            bad(f"{kind} valid sample {i}: schema {errs[:1]}, C {'accepts' if acc else out.strip()[-200:]}")
        else:
            ok(f"{kind} valid sample {i}: schema and C accept")
    for i, s in enumerate(SAMPLES[kind]["invalid"]):
        path = f"{kind}_invalid{i}.json"
        json.dump(s, open(path, "w"))
        schema_rejects = not v.is_valid(s)
        if not can_c:
            (ok if schema_rejects else bad)(f"{kind} invalid sample {i}: schema rejects (no cave run)")
            continue
        acc, out = c_check(kind, path)
        lines = out.strip().splitlines()
        named = [l for l in lines if path in l]
        last = named[0] if named else (lines[-1] if lines else "")
        if schema_rejects and not acc and path in out:
            ok(f"{kind} invalid sample {i}: schema and C reject: {last}")
        else:
            bad(f"{kind} invalid sample {i} {json.dumps(s)}: schema {'rejects' if schema_rejects else 'ACCEPTS'}, "
                f"C {'ACCEPTS' if acc else 'rejects'}: {last}")

print(f"{passed} passed, {failed} failed")
sys.exit(1 if failed else 0)
