#!/usr/bin/python3
"""Test solids of the dissertation's sphere-fit experiments (section 4.4, Figs. 4.21-4.25),
written as OFF files with the true shape of every face beside them (OUT.truth, one id per
face):

  cube_sphere  a cube [-1, 1]^3 whose top face carries a spherical cap (Fig. 4.21: "a cube
               and a spherical patch"): the top is the square minus a disc of radius 0.6, the
               cap is the part of a sphere of radius 0.8 above that circle. 7 shapes: 6 planes
               and 1 sphere.
  beads11      11 spherical zones along the z axis (Fig. 4.23: "11 spherical patches"), the
               model of tests' SphericalBeads(11, 12, 48): zone i on the sphere through the
               unit circles at z = i and z = i + 1, the two end zones closed to their poles.

  patches12    a height field over [0, 4] x [0, 3]: the upper envelope of one sphere per unit
               cell, radii 0.8..2.8 (the model of tests' SphericalPatches(4, 3, R)): 12 patches
               of different curvature meeting along curves the tessellation does not follow
               (open mesh; faces oriented upwards).

  sphere_models.py cube_sphere OUT.off [--segments 64] [--rings 8]
  sphere_models.py patches12 OUT.off [--rings R (grid squares per unit, default 16)]
  sphere_models.py beads11 OUT.off [--rings 12] [--segments 48]
Faces are oriented outwards (every model is star-shaped about a point on its axis).
"""
import argparse
import math


def write(path, vertices, faces, truth, centre):
    # Orient each face outwards: its normal points away from `centre` (None: as given).
    oriented = [] if centre is not None else list(faces)
    for a, b, c in (faces if centre is not None else []):
        pa, pb, pc = vertices[a], vertices[b], vertices[c]
        u = [pb[i] - pa[i] for i in range(3)]
        v = [pc[i] - pa[i] for i in range(3)]
        n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        m = [(pa[i] + pb[i] + pc[i]) / 3 - centre[i] for i in range(3)]
        oriented.append((a, b, c) if sum(n[i] * m[i] for i in range(3)) >= 0 else (a, c, b))
    with open(path, "w") as f:
        f.write(f"OFF\n{len(vertices)} {len(oriented)} 0\n")
        for p in vertices:
            f.write(f"{p[0]:.9g} {p[1]:.9g} {p[2]:.9g}\n")
        for a, b, c in oriented:
            f.write(f"3 {a} {b} {c}\n")
    with open(path.rsplit(".", 1)[0] + ".truth", "w") as f:
        f.write("\n".join(str(t) for t in truth) + "\n")


def cube_sphere(segments, rings):
    assert segments % 8 == 0, "segments must be a multiple of 8 (the square's corners)"
    a, r, big_r = 1.0, 0.6, 0.8
    centre_z = a - math.sqrt(big_r * big_r - r * r)  # the cap's sphere meets z = a at radius r
    vertices, faces, truth = [], [], []
    index = {}

    def vertex(p):
        key = tuple(round(x, 9) for x in p)
        if key not in index:
            index[key] = len(vertices)
            vertices.append(p)
        return index[key]

    angles = [2 * math.pi * j / segments for j in range(segments)]
    square = [(a * math.cos(t) / max(abs(math.cos(t)), abs(math.sin(t))),
               a * math.sin(t) / max(abs(math.cos(t)), abs(math.sin(t)))) for t in angles]
    # The top: rings from the circle to the square (shape 0, the plane z = a).
    top_rings = []
    for i in range(rings + 1):
        s = i / rings
        top_rings.append([vertex(((1 - s) * r * math.cos(t) + s * q[0],
                                  (1 - s) * r * math.sin(t) + s * q[1], a))
                          for t, q in zip(angles, square)])
    for i in range(rings):
        lo, hi = top_rings[i], top_rings[i + 1]
        for j in range(segments):
            k = (j + 1) % segments
            faces += [(lo[j], hi[j], hi[k]), (lo[j], hi[k], lo[k])]
            truth += [0, 0]
    # The cap (shape 6): polar rings on the sphere from the circle up to the pole.
    phi_edge = math.acos((a - centre_z) / big_r)  # polar angle of the circle
    cap_rings = [top_rings[0]]
    for i in range(1, rings):
        phi = phi_edge * (1 - i / rings)
        rho, z = big_r * math.sin(phi), centre_z + big_r * math.cos(phi)
        cap_rings.append([vertex((rho * math.cos(t), rho * math.sin(t), z)) for t in angles])
    for i in range(rings - 1):
        lo, hi = cap_rings[i], cap_rings[i + 1]
        for j in range(segments):
            k = (j + 1) % segments
            faces += [(lo[j], hi[j], hi[k]), (lo[j], hi[k], lo[k])]
            truth += [6, 6]
    pole = vertex((0.0, 0.0, centre_z + big_r))
    for j in range(segments):
        faces.append((cap_rings[-1][j], pole, cap_rings[-1][(j + 1) % segments]))
        truth.append(6)
    # The four sides (shapes 1-4): below each edge of the square, the same x (or y)
    # positions at every height; the bottom (shape 5): a fan from its centre.
    outer = top_rings[-1]
    levels = rings * 2
    columns = [[] for _ in range(segments)]  # per square vertex, its column down to z = -a
    for j in range(segments):
        x, y, _ = vertices[outer[j]]
        columns[j] = [outer[j]] + [vertex((x, y, a - 2 * a * h / levels))
                                   for h in range(1, levels + 1)]
    for j in range(segments):
        k = (j + 1) % segments
        xj, yj, _ = vertices[outer[j]]
        xk, yk, _ = vertices[outer[k]]
        side = (1 if abs(xj - a) < 1e-9 and abs(xk - a) < 1e-9 else
                2 if abs(yj - a) < 1e-9 and abs(yk - a) < 1e-9 else
                3 if abs(xj + a) < 1e-9 and abs(xk + a) < 1e-9 else 4)
        for h in range(levels):
            p, q = columns[j], columns[k]
            faces += [(p[h], q[h], q[h + 1]), (p[h], q[h + 1], p[h + 1])]
            truth += [side, side]
    bottom = vertex((0.0, 0.0, -a))
    for j in range(segments):
        faces.append((columns[j][-1], columns[(j + 1) % segments][-1], bottom))
        truth.append(5)
    return vertices, faces, truth, (0.0, 0.0, 0.0)


def beads(patches, rings, segments):
    spheres = []
    for i in range(patches):
        c = (2.0 * i + 1.0) / 2.0  # through the unit circles at z = i and z = i + 1
        spheres.append((c, math.sqrt(1.0 + (i - c) ** 2)))
    vertices, faces, truth = [], [], []

    def ring(z, rho):
        first = len(vertices)
        for j in range(segments):
            t = 2 * math.pi * j / segments
            vertices.append((rho * math.cos(t), rho * math.sin(t), z))
        return first

    def profile(s, z):
        return math.sqrt(max(0.0, s[1] ** 2 - (z - s[0]) ** 2))

    def band(lower, upper, zone):
        for j in range(segments):
            a, b = lower + j, lower + (j + 1) % segments
            c, d = upper + j, upper + (j + 1) % segments
            faces.extend([(a, b, d), (a, d, c)])
            truth.extend([zone, zone])

    def fan(pole, first, zone):
        for j in range(segments):
            faces.append((pole, first + j, first + (j + 1) % segments))
            truth.append(zone)

    s0 = spheres[0]
    bottom_pole = s0[0] - s0[1]
    vertices.append((0.0, 0.0, bottom_pole))
    previous = None
    for r in range(1, rings + 1):
        z = bottom_pole + (0.0 - bottom_pole) * r / rings
        current = ring(z, 1.0 if r == rings else profile(s0, z))
        if previous is None:
            fan(0, current, 0)
        else:
            band(previous, current, 0)
        previous = current
    for i in range(patches):
        for r in range(1, rings + 1):
            z = i + r / rings
            current = ring(z, 1.0 if r == rings else profile(spheres[i], z))
            band(previous, current, i)
            previous = current
    s = spheres[-1]
    top_pole = s[0] + s[1]
    for r in range(1, rings):
        z = patches + (top_pole - patches) * r / rings
        current = ring(z, profile(s, z))
        band(previous, current, patches - 1)
        previous = current
    vertices.append((0.0, 0.0, top_pole))
    fan(len(vertices) - 1, previous, patches - 1)
    # Star-shaped about each zone's centre, not one point: orient by the axis instead.
    return vertices, faces, truth, None


def patches(columns, rows, resolution):
    spheres = []
    for j in range(rows):
        for i in range(columns):
            index = j * columns + i
            radius = 0.8 + 0.5 * ((index * 7) % 5)
            top = 1.0 + 0.1 * (index % 3)
            spheres.append((i + 0.5, j + 0.5, top - radius, radius))

    def highest(x, y):
        best, z = -1, -1e30
        for s, (cx, cy, cz, r) in enumerate(spheres):
            r2 = r * r - (x - cx) ** 2 - (y - cy) ** 2
            if r2 > 0 and cz + math.sqrt(r2) > z:
                best, z = s, cz + math.sqrt(r2)
        return best, z

    nx, ny = columns * resolution, rows * resolution
    vertices = []
    for y in range(ny + 1):
        for x in range(nx + 1):
            px, py = x / resolution, y / resolution
            vertices.append((px, py, highest(px, py)[1]))
    faces, truth = [], []
    for y in range(ny):
        for x in range(nx):
            a = y * (nx + 1) + x
            b, c = a + 1, a + nx + 1
            d = c + 1
            for face in ((a, b, c), (c, b, d)):
                faces.append(face)
                cx = sum(vertices[i][0] for i in face) / 3
                cy = sum(vertices[i][1] for i in face) / 3
                truth.append(highest(cx, cy)[0])
    return vertices, faces, truth


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", choices=["cube_sphere", "beads11", "patches12"])
    parser.add_argument("out")
    parser.add_argument("--segments", type=int, default=None)
    parser.add_argument("--rings", type=int, default=None)
    args = parser.parse_args()
    if args.model == "patches12":
        v, f, t = patches(4, 3, args.rings or 16)
        write(args.out, v, f, t, None)
    elif args.model == "cube_sphere":
        v, f, t, centre = cube_sphere(args.segments or 64, args.rings or 8)
        write(args.out, v, f, t, centre)
    else:
        v, f, t, _ = beads(11, args.rings or 12, args.segments or 48)
        # Outwards = away from the axis point at the face's height (each zone is a surface
        # of revolution, so that is the outside), and down / up at the poles.
        oriented = []
        for a, b, c in f:
            pa, pb, pc = v[a], v[b], v[c]
            u = [pb[i] - pa[i] for i in range(3)]
            w = [pc[i] - pa[i] for i in range(3)]
            n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]]
            m = [(pa[i] + pb[i] + pc[i]) / 3 for i in range(3)]
            axis = (0.0, 0.0, m[2])
            out = [m[i] - axis[i] for i in range(3)]
            if abs(out[0]) + abs(out[1]) < 1e-12:
                out = [0, 0, m[2] - 5.5]
            oriented.append((a, b, c) if sum(n[i] * out[i] for i in range(3)) >= 0 else (a, c, b))
        write(args.out, v, oriented, t, None)


if __name__ == "__main__":
    main()
