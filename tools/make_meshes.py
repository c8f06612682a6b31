#!/usr/bin/env python3
"""Writes the OBJ meshes the sensor scene draws obstacles and vehicle bodies with
(config/meshes/, docs/sensors.md "Meshes"): rock, tree, bush and vehicle_body (HMMWV-like),
with their materials in meshes.mtl. Coordinates: x forward, y left, z up; the scene fits each
mesh's bounding box to the obstacle's (or the vehicle body's) box, so only proportions matter.
Deterministic: the rock's and bush's lumps come from a fixed integer hash, not a random
generator. Run: tools/make_meshes.py [OUT_DIR] (default config/meshes)."""
import math
import os
import sys

MATERIALS = {  # name: diffuse colour (linear RGB)
    "rock": (0.42, 0.38, 0.34),
    "bark": (0.30, 0.20, 0.12),
    "foliage": (0.12, 0.40, 0.10),
    "leaves": (0.20, 0.50, 0.15),
    "body": (0.35, 0.33, 0.22),  # replaced by the vehicle's colour when drawn
    "glass": (0.05, 0.07, 0.09),
    "lights": (0.90, 0.88, 0.75),
    "grille": (0.10, 0.10, 0.10),
}


class Mesh:
    def __init__(self):
        self.v = []
        self.groups = []  # (material, [faces]); faces index self.v from 0

    def vertex(self, p):
        self.v.append(tuple(float(c) for c in p))
        return len(self.v) - 1

    def face(self, material, idx):
        if not self.groups or self.groups[-1][0] != material:
            self.groups.append((material, []))
        self.groups[-1][1].append(list(idx))

    def write(self, path, name):
        with open(path, "w") as f:
            f.write("# %s: written by tools/make_meshes.py (edit that, not this file)\n" % name)
            f.write("mtllib meshes.mtl\no %s\n" % name)
            for p in self.v:
                f.write("v %.4f %.4f %.4f\n" % p)
            for material, faces in self.groups:
                f.write("usemtl %s\n" % material)
                for face in faces:
                    f.write("f " + " ".join(str(i + 1) for i in face) + "\n")


def lump(*ints):
    """A deterministic value in [-1, 1] from integers (an integer hash, no RNG state)."""
    h = 2166136261
    for i in ints:
        h = ((h ^ (i & 0xFFFFFFFF)) * 16777619) & 0xFFFFFFFF
    h ^= h >> 13
    h = (h * 0x5BD1E995) & 0xFFFFFFFF
    h ^= h >> 15
    return h / 0x7FFFFFFF - 1.0


def icosphere(levels):
    t = (1.0 + 5 ** 0.5) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
             (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [tuple(c / math.sqrt(sum(x * x for x in v)) for c in v) for v in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        cache, out = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = [(verts[a][k] + verts[b][k]) / 2 for k in range(3)]
                n = math.sqrt(sum(x * x for x in m))
                verts.append(tuple(x / n for x in m))
                cache[key] = len(verts) - 1
            return cache[key]

        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            out += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = out
    return verts, faces


def blob(mesh, material, centre, radii, levels, roughness, seed, flat_bottom=None):
    verts, faces = icosphere(levels)
    base = len(mesh.v)
    for k, (x, y, z) in enumerate(verts):
        s = 1.0 + roughness * lump(seed, k)
        p = [centre[0] + radii[0] * s * x, centre[1] + radii[1] * s * y, centre[2] + radii[2] * s * z]
        if flat_bottom is not None:
            p[2] = max(p[2], flat_bottom)
        mesh.vertex(p)
    for f in faces:
        mesh.face(material, [base + i for i in f])


def cone(mesh, material, z0, z1, r0, r1, sides, cap_bottom=True, cap_top=True):
    """Frustum around the z axis from radius r0 at z0 to r1 at z1 (r1 = 0: a cone)."""
    b = len(mesh.v)
    for z, r in ((z0, r0), (z1, r1)):
        for s in range(sides):
            a = 2 * math.pi * s / sides
            mesh.vertex((r * math.cos(a), r * math.sin(a), z))
    for s in range(sides):
        t = (s + 1) % sides
        mesh.face(material, [b + s, b + t, b + sides + t, b + sides + s])
    if cap_bottom:
        mesh.face(material, [b + s for s in reversed(range(sides))])
    if cap_top and r1 > 0:
        mesh.face(material, [b + sides + s for s in range(sides)])


def prism(mesh, material, profile, y0, y1):
    """A convex polygon in the xz plane (counter-clockwise seen from +y) extruded over y0..y1."""
    n = len(profile)
    b = len(mesh.v)
    for y in (y0, y1):
        for x, z in profile:
            mesh.vertex((x, y, z))
    mesh.face(material, [b + k for k in range(n)])
    mesh.face(material, [b + n + k for k in reversed(range(n))])
    for k in range(n):
        j = (k + 1) % n
        mesh.face(material, [b + k, b + j, b + n + j, b + n + k])


def quad(mesh, material, corners):
    mesh.face(material, [mesh.vertex(c) for c in corners])


def rock():
    m = Mesh()
    blob(m, "rock", (0, 0, 0), (1.0, 0.85, 0.7), 2, 0.18, 7, flat_bottom=-0.55)
    return m


def tree():
    m = Mesh()
    cone(m, "bark", -1.0, -0.35, 0.16, 0.12, 10)
    for z0, z1, r in ((-0.55, 0.25, 1.0), (-0.1, 0.65, 0.78), (0.3, 1.0, 0.52)):
        cone(m, "foliage", z0, z1, r, 0.0, 12)
    return m


def bush():
    m = Mesh()
    for k, (c, r) in enumerate((((0.0, 0.0, -0.1), (0.75, 0.75, 0.7)),
                                ((0.45, 0.2, -0.3), (0.55, 0.5, 0.5)),
                                ((-0.4, 0.3, -0.35), (0.55, 0.55, 0.45)),
                                ((0.1, -0.45, -0.3), (0.6, 0.5, 0.5)),
                                ((-0.2, -0.1, 0.25), (0.5, 0.5, 0.55)))):
        blob(m, "leaves", c, r, 1, 0.15, 100 + k, flat_bottom=-0.75)
    return m


def vehicle_body():
    """HMMWV-like, fitted by the scene into the body boxes' bounding box: z = -1 at the axle
    line, the fenders from z = 0 (above the tyres), the hull between the wheels |y| < 0.65."""
    m = Mesh()
    prism(m, "body", [(-0.97, -1.0), (0.97, -1.0), (0.97, 0.0), (-0.97, 0.0)], -0.65, 0.65)  # hull
    # Deck over the wheels: hood sloping to the nose, flat rear cargo bed.
    prism(m, "body", [(-1.0, 0.0), (1.0, 0.0), (1.0, 0.2), (0.93, 0.3), (-1.0, 0.3)], -1.0, 1.0)
    # Cabin: raked windscreen, flat roof, vertical back.
    cab = [(-0.55, 0.3), (0.28, 0.3), (0.08, 1.0), (-0.55, 1.0)]
    prism(m, "body", cab, -0.88, 0.88)
    # Windows, 1 % proud of the cabin faces: windscreen, side windows, rear window.
    e = 0.012
    (xb, zb), (xt, zt) = (0.28, 0.3), (0.08, 1.0)
    nx, nz = (zt - zb), -(xt - xb)  # outward normal of the windscreen (x forward, z up)
    nn = math.hypot(nx, nz)
    nx, nz = nx / nn * e, nz / nn * e

    def on_screen(t, y):
        return (xb + t * (xt - xb) + nx, y, zb + t * (zt - zb) + nz)

    quad(m, "glass", [on_screen(0.22, -0.78), on_screen(0.22, 0.78), on_screen(0.9, 0.78),
                      on_screen(0.9, -0.78)])
    for side in (-1.0, 1.0):
        y = side * (0.88 + e)
        quad(m, "glass", [(-0.48, y, 0.5), (0.1, y, 0.5), (0.0, y, 0.92), (-0.48, y, 0.92)])
    quad(m, "glass", [(-0.55 - e, -0.7, 0.55), (-0.55 - e, 0.7, 0.55), (-0.55 - e, 0.7, 0.9),
                      (-0.55 - e, -0.7, 0.9)])
    # Grille and headlights on the nose.
    quad(m, "grille", [(1.0 + e, -0.45, 0.03), (1.0 + e, 0.45, 0.03), (1.0 + e, 0.45, 0.17),
                       (1.0 + e, -0.45, 0.17)])
    for side in (-1.0, 1.0):
        quad(m, "lights", [(1.0 + e, side * 0.6, 0.06), (1.0 + e, side * 0.85, 0.06),
                           (1.0 + e, side * 0.85, 0.16), (1.0 + e, side * 0.6, 0.16)])
    return m


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "..", "config", "meshes")
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "meshes.mtl"), "w") as f:
        f.write("# Materials of the scene meshes: written by tools/make_meshes.py\n")
        for name, (r, g, b) in MATERIALS.items():
            f.write("newmtl %s\nKd %.3f %.3f %.3f\n" % (name, r, g, b))
    for name, make in (("rock", rock), ("tree", tree), ("bush", bush),
                       ("vehicle_body", vehicle_body)):
        make().write(os.path.join(out, name + ".obj"), name)


if __name__ == "__main__":
    main()
