#!/usr/bin/env python3
"""Helpers for make_demo_scene.sh (standard library only).

Subcommands:
  poses VARIANT WIDTH HEIGHT FOV_DEG GT_DIR
      Prints one line per view, "name cam_x cam_y cam_z look_x look_y look_z" in POV-Ray's frame, and
      writes the ground-truth poses as a COLMAP text model GT_DIR/{cameras,images,points3D}.txt.
  strip-jpeg FILE...
      Removes comment and APPn (n>0) segments, so the JPEG bytes do not depend on the render date.
  compare SPARSE_DIR GT_DIR
      Aligns COLMAP's camera poses (sparse/0/*.bin) to the ground truth by a similarity (rotation from the
      camera orientations, then scale and translation by least squares), prints rotation and camera-centre
      errors, and exits non-zero if they exceed 1 degree or 2% of the camera-ring radius.

Frames: POV-Ray is left-handed with y up. The ground-truth world frame is right-handed with z up:
world (x, y, z) = POV-Ray (x, z, y). Cameras follow COLMAP: x right, y down, z forward; pose = world-to-camera.
"""
import math
import os
import struct
import sys

# Camera rings per variant: radius, heights (world z), look-at point (world), views per ring, azimuth offset
# of the upper ring in degrees (so the two rings do not share azimuths).
RINGS = {
    1: dict(radius=6.5, heights=(1.6, 3.4), look=(0.0, 0.0, 0.6), per_ring=24, upper_offset=7.5),
    2: dict(radius=6.0, heights=(1.4, 3.0), look=(0.0, 0.0, 0.7), per_ring=24, upper_offset=7.5),
}


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def dot(a, b):
    return sum(a[i] * b[i] for i in range(3))


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def normalize(a):
    n = math.sqrt(dot(a, a))
    return [x / n for x in a]


def mat_vec(m, v):
    return [dot(row, v) for row in m]


def transpose(m):
    return [[m[j][i] for j in range(3)] for i in range(3)]


def mat_mul(a, b):
    bt = transpose(b)
    return [[dot(a[i], bt[j]) for j in range(3)] for i in range(3)]


def quat_to_rot(q):
    """Unit quaternion (w, x, y, z) -> 3x3 rotation matrix (rows)."""
    w, x, y, z = q
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]


def rot_to_quat(m):
    """3x3 rotation matrix -> unit quaternion (w, x, y, z) with w >= 0."""
    trace = m[0][0] + m[1][1] + m[2][2]
    if trace > 0:
        s = 2 * math.sqrt(trace + 1)
        q = [s / 4, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s]
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = 2 * math.sqrt(1 + m[0][0] - m[1][1] - m[2][2])
        q = [(m[2][1] - m[1][2]) / s, s / 4, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s]
    elif m[1][1] > m[2][2]:
        s = 2 * math.sqrt(1 + m[1][1] - m[0][0] - m[2][2])
        q = [(m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, s / 4, (m[1][2] + m[2][1]) / s]
    else:
        s = 2 * math.sqrt(1 + m[2][2] - m[0][0] - m[1][1])
        q = [(m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, s / 4]
    if q[0] < 0:
        q = [-x for x in q]
    n = math.sqrt(sum(x * x for x in q))
    return [x / n for x in q]


def rotation_angle_deg(m):
    c = (m[0][0] + m[1][1] + m[2][2] - 1) / 2
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def focal_px(width, fov_deg):
    # POV-Ray's "angle" is the horizontal field of view across the full image width.
    return (width / 2) / math.tan(math.radians(fov_deg) / 2)


def ring_views(variant):
    """List of (name, centre_world, look_world)."""
    ring = RINGS[variant]
    views = []
    for ring_index, height in enumerate(ring["heights"]):
        offset = ring["upper_offset"] if ring_index == 1 else 0.0
        for k in range(ring["per_ring"]):
            azimuth = math.radians(offset + 360.0 * k / ring["per_ring"])
            centre = [ring["radius"] * math.cos(azimuth), ring["radius"] * math.sin(azimuth), height]
            name = "view_%03d.jpg" % len(views)
            views.append((name, centre, list(ring["look"])))
    return views


def world_to_camera(centre, look):
    """COLMAP pose (R rows = camera x, y, z axes in world; t = -R C) of a camera at centre looking at look."""
    forward = normalize(sub(look, centre))
    right = normalize(cross(forward, [0.0, 0.0, 1.0]))
    down = cross(forward, right)
    rotation = [right, down, forward]
    translation = [-x for x in mat_vec(rotation, centre)]
    return rotation, translation


def write_text(path, text):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def cmd_poses(variant, width, height, fov_deg, gt_dir):
    variant, width, height, fov_deg = int(variant), int(width), int(height), float(fov_deg)
    if variant not in RINGS:
        sys.exit("demo_scene_tools: unknown variant %d (known: %s)" % (variant, sorted(RINGS)))
    os.makedirs(gt_dir, exist_ok=True)
    f = focal_px(width, fov_deg)
    write_text(os.path.join(gt_dir, "cameras.txt"),
               "# Ground truth of the POV-Ray render (exact pinhole, no distortion).\n"
               "# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
               "1 PINHOLE %d %d %.10f %.10f %.10f %.10f\n" % (width, height, f, f, width / 2, height / 2))
    lines = ["# Ground-truth world-to-camera poses; world frame = POV-Ray (x, z, y), z up.",
             "# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME", "# (no POINTS2D)"]
    for image_id, (name, centre, look) in enumerate(ring_views(variant), start=1):
        rotation, translation = world_to_camera(centre, look)
        q = rot_to_quat(rotation)
        lines.append("%d %s %s 1 %s" % (image_id, " ".join("%.12f" % x for x in q),
                                        " ".join("%.12f" % x for x in translation), name))
        lines.append("")
        # POV-Ray frame = (x, z, y) of the world frame.
        print(name, "%.9f %.9f %.9f %.9f %.9f %.9f" % (centre[0], centre[2], centre[1], look[0], look[2], look[1]))
    write_text(os.path.join(gt_dir, "images.txt"), "\n".join(lines) + "\n")
    write_text(os.path.join(gt_dir, "points3D.txt"), "# No points: ground truth holds poses only.\n")


def cmd_strip_jpeg(*paths):
    for path in paths:
        with open(path, "rb") as f:
            data = f.read()
        if data[:2] != b"\xff\xd8":
            sys.exit("demo_scene_tools: %s: not a JPEG file" % path)
        out = bytearray(data[:2])
        pos = 2
        while True:
            if pos + 4 > len(data) or data[pos] != 0xFF:
                sys.exit("demo_scene_tools: %s: truncated or malformed JPEG segment at byte %d" % (path, pos))
            marker = data[pos + 1]
            length = struct.unpack(">H", data[pos + 2:pos + 4])[0]
            segment = data[pos:pos + 2 + length]
            if marker == 0xDA:  # start of scan: the rest is entropy-coded data
                out += data[pos:]
                break
            if not (marker == 0xFE or 0xE1 <= marker <= 0xEF):
                out += segment
            pos += 2 + length
        write_bytes = bytes(out)
        with open(path + ".tmp", "wb") as f:
            f.write(write_bytes)
        os.replace(path + ".tmp", path)


def read_colmap_images_bin(path):
    """image name -> (qvec, tvec)."""
    poses = {}
    with open(path, "rb") as f:
        (count,) = struct.unpack("<Q", f.read(8))
        for _ in range(count):
            header = struct.unpack("<I7dI", f.read(4 + 56 + 4))
            name = bytearray()
            while True:
                c = f.read(1)
                if c in (b"\0", b""):
                    break
                name += c
            (num_points2d,) = struct.unpack("<Q", f.read(8))
            f.seek(24 * num_points2d, 1)
            poses[name.decode()] = (header[1:5], header[5:8])
    return poses


def read_colmap_cameras_bin(path):
    params_per_model = {0: 3, 1: 4, 2: 4, 3: 5, 4: 8, 5: 8, 6: 12, 7: 5, 8: 4, 9: 5, 10: 12}
    cameras = []
    with open(path, "rb") as f:
        (count,) = struct.unpack("<Q", f.read(8))
        for _ in range(count):
            camera_id, model_id, width, height = struct.unpack("<iiQQ", f.read(24))
            params = struct.unpack("<%dd" % params_per_model[model_id], f.read(8 * params_per_model[model_id]))
            cameras.append((camera_id, model_id, width, height, params))
    return cameras


def read_gt_images_txt(path):
    poses = {}
    with open(path) as f:
        for line in f:
            fields = line.split()
            if len(fields) == 10 and not line.startswith("#"):
                poses[fields[9]] = ([float(x) for x in fields[1:5]], [float(x) for x in fields[5:8]])
    return poses


def camera_centre(rotation, translation):
    return [-x for x in mat_vec(transpose(rotation), translation)]


def cmd_compare(sparse_dir, gt_dir):
    estimated = read_colmap_images_bin(os.path.join(sparse_dir, "images.bin"))
    truth = read_gt_images_txt(os.path.join(gt_dir, "images.txt"))
    names = sorted(set(estimated) & set(truth))
    if len(names) < 3:
        sys.exit("demo_scene_tools: only %d images in common with the ground truth" % len(names))
    est_rot = {n: quat_to_rot(estimated[n][0]) for n in names}
    gt_rot = {n: quat_to_rot(truth[n][0]) for n in names}
    # x_cam = R_est c + t_est = R_gt g + t_gt with c = s Q g + T  =>  Q = R_est^T R_gt for every image.
    quats = [rot_to_quat(mat_mul(transpose(est_rot[n]), gt_rot[n])) for n in names]
    mean = [0.0] * 4
    for q in quats:
        sign = 1.0 if sum(q[i] * quats[0][i] for i in range(4)) >= 0 else -1.0
        mean = [mean[i] + sign * q[i] for i in range(4)]
    norm = math.sqrt(sum(x * x for x in mean))
    align = quat_to_rot([x / norm for x in mean])
    rotation_errors = [rotation_angle_deg(mat_mul(transpose(align), mat_mul(transpose(est_rot[n]), gt_rot[n])))
                       for n in names]
    est_c = [camera_centre(est_rot[n], estimated[n][1]) for n in names]
    gt_c = [mat_vec(align, camera_centre(gt_rot[n], truth[n][1])) for n in names]
    est_mean = [sum(c[i] for c in est_c) / len(names) for i in range(3)]
    gt_mean = [sum(c[i] for c in gt_c) / len(names) for i in range(3)]
    numerator = sum(dot(sub(e, est_mean), sub(g, gt_mean)) for e, g in zip(est_c, gt_c))
    denominator = sum(dot(sub(g, gt_mean), sub(g, gt_mean)) for g in gt_c)
    scale = numerator / denominator
    # Centre errors in ground-truth units (the similarity's scale divided out).
    centre_errors = [math.sqrt(dot(sub(sub(e, est_mean), [scale * x for x in sub(g, gt_mean)]),
                                   sub(sub(e, est_mean), [scale * x for x in sub(g, gt_mean)]))) / abs(scale)
                     for e, g in zip(est_c, gt_c)]
    radius = max(math.hypot(*camera_centre(gt_rot[n], truth[n][1])[:2]) for n in names)
    print("ground truth: %d common images; rotation error mean %.3f max %.3f deg; centre error mean %.4f max "
          "%.4f (ring radius %.2f)" % (len(names), sum(rotation_errors) / len(names), max(rotation_errors),
                                      sum(centre_errors) / len(names), max(centre_errors), radius))
    with open(os.path.join(gt_dir, "cameras.txt")) as f:
        gt_camera = [line.split() for line in f if line.strip() and not line.startswith("#")][0]
    for camera_id, model_id, width, height, params in read_colmap_cameras_bin(
            os.path.join(sparse_dir, "cameras.bin")):
        print("camera %d: model id %d, %dx%d, params %s (ground truth %s)" %
              (camera_id, model_id, width, height, " ".join("%.3f" % p for p in params),
               " ".join("%.3f" % float(p) for p in gt_camera[4:])))
    if max(rotation_errors) > 1.0 or max(centre_errors) > 0.02 * radius:
        sys.exit("demo_scene_tools: COLMAP's poses disagree with the ground truth beyond 1 deg / 2% of the radius")


def main():
    commands = {"poses": cmd_poses, "strip-jpeg": cmd_strip_jpeg, "compare": cmd_compare}
    if len(sys.argv) < 2 or sys.argv[1] not in commands:
        sys.exit(__doc__)
    commands[sys.argv[1]](*sys.argv[2:])


if __name__ == "__main__":
    main()
