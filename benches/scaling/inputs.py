"""Inputs of the scaling study (benches/scaling.sh): experiments that vary one
thing at a time around the quickstart (tabletop, UR5 + laser, 1 cm).

    python3 inputs.py REPO OUT_DIR AXIS VALUE  -> prints the experiment path

AXIS: viewpoints (count), beams (angular step, degrees), triangles (count of
a tessellated sphere on the table), workspace (m^3). Every path written is
absolute, so the files can live anywhere.
"""
import math
import os
import re
import sys

REPO, OUT, AXIS, VALUE = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
os.makedirs(OUT, exist_ok=True)
EXPERIMENTS = os.path.join(REPO, "experiments")
QUICKSTART = open(os.path.join(EXPERIMENTS, "quickstart.toml")).read()
TABLETOP_PATH = os.path.join(REPO, "scenes", "tabletop.toml")
TABLETOP = open(TABLETOP_PATH).read()


def absolute_scene(text):
    """The tabletop scene text with its mesh path made absolute."""
    return text.replace(
        'file = "meshes/', 'file = "%s/' % os.path.join(REPO, "scenes", "meshes")
    )


def viewpoints(count):
    """`count` reachable look-at viewpoints around the table, on the robot's
    side (the quickstart's six are of this kind)."""
    out = []
    for i in range(count):
        # Azimuths over the half circle facing the robot, three tilts.
        theta = math.radians(90 + 180 * (i + 0.5) / count)
        spread = (0.25, 0.45, 0.65)[i % 3]
        look = (0.1 * math.cos(2.4 * i), 0.1 * math.sin(2.4 * i), 0.05)
        out.append(
            "[[viewpoint]]\nlook_at = [%.4f, %.4f, %.4f]\nfrom = [%.4f, %.4f, 1.0]\ndistance = 0.45\n"
            % (look + (spread * math.cos(theta), spread * math.sin(theta)))
        )
    return "\n".join(out)


def experiment(name, scene_path, step_deg=0.5, views=None):
    """The quickstart with another scene, angular step or viewpoints; one
    seed, the ray update and the unscented merge."""
    head = QUICKSTART.split("[[viewpoint]]")[0]
    head = re.sub(r'^name = ".*"', 'name = "%s"' % name, head, flags=re.M)
    head = re.sub(r'^scene = ".*"', 'scene = "%s"' % scene_path, head, flags=re.M)
    head = re.sub(
        r'^error_profile = "(.*)"',
        lambda m: 'error_profile = "%s"' % os.path.join(EXPERIMENTS, m.group(1)),
        head,
        flags=re.M,
    )
    head = re.sub(
        r'^urdf = "(.*)"',
        lambda m: 'urdf = "%s"' % os.path.normpath(os.path.join(EXPERIMENTS, m.group(1))),
        head,
        flags=re.M,
    )
    head = re.sub(r"^seeds = .*$", "seeds = [1]", head, flags=re.M)
    head = re.sub(r"^methods = .*$", 'methods = ["ray_update", "unscented"]', head, flags=re.M)
    head = re.sub(r"^(horizontal|vertical)_step_deg = .*$", lambda m: "%s_step_deg = %g" % (m.group(1), step_deg), head, flags=re.M)
    body = viewpoints(views) if views else "[[viewpoint]]" + QUICKSTART.split("[[viewpoint]]", 1)[1]
    path = os.path.join(OUT, name + ".toml")
    with open(path, "w") as f:
        f.write(head + body)
    return path


def sphere_scene(triangles):
    """The table and a UV sphere of about `triangles` triangles (OBJ)."""
    rings = max(3, round(math.sqrt(triangles / 4)))
    segments = 2 * rings
    obj = os.path.join(OUT, "sphere_%d.obj" % triangles)
    with open(obj, "w") as f:
        f.write("v 0 0 1\n")
        for r in range(1, rings):
            phi = math.pi * r / rings
            for s in range(segments):
                t = 2 * math.pi * s / segments
                f.write("v %.7f %.7f %.7f\n" % (math.sin(phi) * math.cos(t), math.sin(phi) * math.sin(t), math.cos(phi)))
        f.write("v 0 0 -1\n")
        bottom = 2 + (rings - 1) * segments - 1 + 1
        ring = lambda r, s: 2 + (r - 1) * segments + s % segments  # 1-based
        for s in range(segments):
            f.write("f 1 %d %d\n" % (ring(1, s), ring(1, s + 1)))
        for r in range(1, rings - 1):
            for s in range(segments):
                a, b = ring(r, s), ring(r, s + 1)
                c, d = ring(r + 1, s), ring(r + 1, s + 1)
                f.write("f %d %d %d\nf %d %d %d\n" % (a, c, d, a, d, b))
        for s in range(segments):
            f.write("f %d %d %d\n" % (bottom, ring(rings - 1, s + 1), ring(rings - 1, s)))
    table = TABLETOP.split("[[object]]")
    scene = table[0] + "[[object]]" + table[1]
    scene = re.sub(r'^name = "tabletop"', 'name = "sphere_%d"' % triangles, scene, flags=re.M)
    scene += '[[object]]\nname = "sphere"\nshape = "mesh"\nfile = "%s"\nscale = 0.1\nxyz = [0.0, 0.0, 0.1]\n' % obj
    path = os.path.join(OUT, "sphere_%d_scene.toml" % triangles)
    with open(path, "w") as f:
        f.write(scene)
    return path


def workspace_scene(volume):
    """The tabletop with its workspace box scaled to `volume` m^3 about its centre."""
    lo, hi = (-0.4, -0.4, -0.04), (0.4, 0.4, 0.36)
    base = math.prod(h - l for l, h in zip(lo, hi))
    f = (volume / base) ** (1 / 3)
    centre = [(l + h) / 2 for l, h in zip(lo, hi)]
    new_lo = [c - (c - l) * f for c, l in zip(centre, lo)]
    new_hi = [c + (h - c) * f for c, h in zip(centre, hi)]
    scene = absolute_scene(TABLETOP)
    scene = re.sub(r"^min = .*$", "min = [%.4f, %.4f, %.4f]" % tuple(new_lo), scene, count=1, flags=re.M)
    scene = re.sub(r"^max = .*$", "max = [%.4f, %.4f, %.4f]" % tuple(new_hi), scene, count=1, flags=re.M)
    path = os.path.join(OUT, "workspace_%g_scene.toml" % volume)
    with open(path, "w") as f:
        f.write(scene)
    return path


def tabletop():
    path = os.path.join(OUT, "tabletop_scene.toml")
    with open(path, "w") as f:
        f.write(absolute_scene(TABLETOP))
    return path


name = "%s_%g" % (AXIS, VALUE)
if AXIS == "viewpoints":
    print(experiment(name, tabletop(), views=int(VALUE)))
elif AXIS == "beams":
    print(experiment(name, tabletop(), step_deg=VALUE))
elif AXIS == "triangles":
    print(experiment(name, sphere_scene(int(VALUE))))
elif AXIS == "workspace":
    print(experiment(name, workspace_scene(VALUE)))
elif AXIS == "resolution":
    print(experiment(name, tabletop()))
else:
    sys.exit("unknown axis " + AXIS)
