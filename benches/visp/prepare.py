#!/usr/bin/env python3
"""Files for ViSP's edge tracker from a pipetrack sequence folder SEQ.

    prepare.py SEQ WORK

writes WORK/model.cao (the sequence's model.cao when it has one, else its
model.json written in ViSP's format: its points and its faces by points),
WORK/vertices.txt (the model's vertices in pipetrack's order: model.json's
own, or, for a .cao model, each vertex found from the truth's projected
corners and poses by linear triangulation over every frame) and prints
the arguments edge_tracker takes after its output file: the intrinsics from
camera.json and the first frame's pose from init.json.
"""
import json
import math
import os
import shutil
import sys


def rotation(r):
    """The rotation matrix of the axis-angle vector r (Rodrigues)."""
    a = math.sqrt(sum(x * x for x in r))
    if a < 1e-15:
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    k = [x / a for x in r]
    c, s, v = math.cos(a), math.sin(a), 1 - math.cos(a)
    return [
        [c + k[0] * k[0] * v, k[0] * k[1] * v - k[2] * s, k[0] * k[2] * v + k[1] * s],
        [k[1] * k[0] * v + k[2] * s, c + k[1] * k[1] * v, k[1] * k[2] * v - k[0] * s],
        [k[2] * k[0] * v - k[1] * s, k[2] * k[1] * v + k[0] * s, c + k[2] * k[2] * v],
    ]


def solve3(a, b):
    """x with a x = b for a 3×3 a (Cramer's rule)."""
    def det(m):
        return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))
    d = det(a)
    out = []
    for j in range(3):
        m = [row[:] for row in a]
        for i in range(3):
            m[i][j] = b[i]
        out.append(det(m) / d)
    return out


def triangulate(seq, cam):
    """Each vertex from its projections in the truth: for u = cx + fx X/Z,
    fx (R1·X + t1) − (u − cx)(R3·X + t3) = 0, and likewise for v, in least squares."""
    frames = [json.loads(line) for line in open(os.path.join(seq, "truth.jsonl")) if line.strip()]
    # Each frame's rotation matrix, translation and projected vertices.
    views = [(rotation(f["pose"]["rotation"]), f["pose"]["translation"], f["corners"]) for f in frames]
    vertices = []
    for i in range(len(frames[0]["corners"])):
        ata = [[0.0] * 3 for _ in range(3)]
        atb = [0.0] * 3
        for r, t, corners in views:
            u, v = corners[i]
            for f_, c, p, row in ((cam["fx"], cam["cx"], u, 0), (cam["fy"], cam["cy"], v, 1)):
                coef = [f_ * r[row][j] - (p - c) * r[2][j] for j in range(3)]
                rhs = (p - c) * t[2] - f_ * t[row]
                for j in range(3):
                    atb[j] += coef[j] * rhs
                    for k in range(3):
                        ata[j][k] += coef[j] * coef[k]
        vertices.append(solve3(ata, atb))
    # The truth's corners are exact projections of one rigid model: each
    # vertex found must project onto them again.
    worst = 0.0
    for r, t, corners in views:
        for x, (u, v) in zip(vertices, corners):
            c = [sum(r[i][j] * x[j] for j in range(3)) + t[i] for i in range(3)]
            if c[2] > 0:
                du = cam["cx"] + cam["fx"] * c[0] / c[2] - u
                dv = cam["cy"] + cam["fy"] * c[1] / c[2] - v
                worst = max(worst, math.hypot(du, dv))
    if worst > 0.01:
        sys.exit(f"{seq}: the truth's corners do not fit one rigid model ({worst:.3g} px off)")
    return vertices


def main():
    seq, work = sys.argv[1], sys.argv[2]
    if not os.path.exists(os.path.join(seq, "truth.jsonl")):
        sys.exit(f"{seq}: no truth.jsonl, which the comparison scores against")
    os.makedirs(work, exist_ok=True)
    cam = json.load(open(os.path.join(seq, "camera.json")))
    if os.path.exists(os.path.join(seq, "model.cao")):
        for name in os.listdir(seq):
            src = os.path.join(seq, name)
            if name.endswith(".cao") or (os.path.isdir(src) and name != "frames"):
                dst = os.path.join(work, name)
                if os.path.isdir(src):
                    shutil.copytree(src, dst, dirs_exist_ok=True)
                else:
                    shutil.copy(src, dst)
        vertices = triangulate(seq, cam)
    else:
        model = json.load(open(os.path.join(seq, "model.json")))
        if model.get("joints"):
            sys.exit(f"{seq}: the model has joints, which ViSP's edge tracker does not model")
        vertices = model["vertices"]
        with open(os.path.join(work, "model.cao"), "w") as cao:
            cao.write(f"V1\n{len(vertices)}\n")
            cao.writelines(f"{x!r} {y!r} {z!r}\n" for x, y, z in vertices)
            cao.write("0\n0\n")
            faces = model["faces"]
            cao.write(f"{len(faces)}\n")
            cao.writelines(f"{len(f)} " + " ".join(str(i) for i in f) + "\n" for f in faces)
            cao.write("0\n0\n")
    with open(os.path.join(work, "vertices.txt"), "w") as out:
        out.writelines(f"{x!r} {y!r} {z!r}\n" for x, y, z in vertices)
    pose = json.load(open(os.path.join(seq, "init.json")))["pose"]
    print(*[cam["fx"], cam["fy"], cam["cx"], cam["cy"]], *pose["translation"], *pose["rotation"])


main()
