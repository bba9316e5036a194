"""A picture of a scene's MuJoCo model at a configuration, from MuJoCo's offscreen renderer.

Rendering needs an OpenGL backend, which MuJoCo picks once per process from ``MUJOCO_GL``. Each
picture is therefore rendered in a child Python process (a broken driver cannot take the caller
down, and the caller's environment is not changed): with ``MUJOCO_GL`` as the user set it, else
with ``egl`` (a GPU or Mesa's software EGL, no display needed), then ``osmesa``. Without a
working backend no picture is made and :class:`NoRendererError` says what each backend answered.

The camera looks at the centre of the geoms' bounding sphere from a distance that fits the
sphere in the vertical field of view; a planar mechanism (its geoms within 2 % of their extent
of a plane) is seen square-on, anything else from azimuth 100 deg, elevation -15 deg.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import zlib

import numpy as np

from .files import PNG_TEXT

WIDTH, HEIGHT = 320, 240
BACKENDS = ("egl", "osmesa")
#: Seconds a child process may take (import, compile, render) before it counts as failed.
TIMEOUT = 120.0


class NoRendererError(Exception):
    """No OpenGL backend could render (the message lists each backend's answer)."""


def encode_png(rgb: np.ndarray) -> bytes:
    """An 8-bit RGB image (height x width x 3) as PNG bytes (no filtering, zlib level 9)."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[i].tobytes() for i in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"tEXt", PNG_TEXT) + chunk(b"IDAT", zlib.compress(raw, 9))
            + chunk(b"IEND", b""))


def render_png(xml: str, qpos: np.ndarray, width: int = WIDTH, height: int = HEIGHT) -> bytes:
    """PNG bytes of the MJCF model ``xml`` at ``qpos`` (MuJoCo's coordinates).

    Raises:
        NoRendererError: no backend rendered; the message says why, backend by backend.
    """
    request = json.dumps({"xml": xml, "qpos": np.asarray(qpos, float).tolist(),
                          "width": int(width), "height": int(height)})
    user = os.environ.get("MUJOCO_GL")
    answers = []
    for backend in (user,) if user else BACKENDS:
        env = dict(os.environ, MUJOCO_GL=backend)
        try:
            done = subprocess.run([sys.executable, "-m", "pinlin.mjcf_picture"],
                                  input=request.encode(), capture_output=True, timeout=TIMEOUT,
                                  env=env, check=False)
        except (OSError, subprocess.TimeoutExpired) as exc:
            answers.append(f"MUJOCO_GL={backend}: {type(exc).__name__}")
            continue
        if done.returncode == 0 and done.stdout.startswith(b"\x89PNG"):
            return done.stdout
        last = (done.stderr.decode(errors="replace").strip().splitlines() or ["no output"])[-1]
        answers.append(f"MUJOCO_GL={backend}: {last[:200]}")
    raise NoRendererError("; ".join(answers))


def _camera(model, data):
    """A free camera (lookat, distance, azimuth, elevation) that frames every geom."""
    import mujoco

    centres = data.geom_xpos if model.ngeom else data.xpos[1:]
    bounds = model.geom_rbound if model.ngeom else np.zeros(len(centres))
    lo = (centres - bounds[:, None]).min(axis=0)
    hi = (centres + bounds[:, None]).max(axis=0)
    centre = (lo + hi) / 2
    radius = max(float(np.max(np.linalg.norm(centres - centre, axis=1) + bounds)), 1e-3)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = centre
    fovy = np.deg2rad(model.vis.global_.fovy)
    cam.distance = 1.1 * radius / np.sin(fovy / 2)
    cam.azimuth, cam.elevation = 100.0, -15.0
    spread = centres - centres.mean(axis=0)
    if len(centres) >= 3:
        _, s, vt = np.linalg.svd(spread, full_matrices=False)
        if s[0] > 0 and s[-1] < 0.02 * s[0]:  # planar: look along the plane's normal
            n = vt[-1] if vt[-1][2] <= 0 else -vt[-1]  # from above rather than from below
            if abs(n[2]) < 1e-9 and n[1] < 0:
                n = -n
            cam.azimuth = float(np.degrees(np.arctan2(n[1], n[0])))
            cam.elevation = float(np.clip(np.degrees(np.arcsin(np.clip(n[2], -1, 1))),
                                          -89.0, 89.0))
    return cam


def _child() -> int:
    import mujoco

    request = json.loads(sys.stdin.buffer.read())
    spec = mujoco.MjSpec.from_string(request["xml"])
    sky = spec.add_texture(name="pinlin_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX)
    sky.builtin = mujoco.mjtBuiltin.mjBUILTIN_GRADIENT
    sky.rgb1, sky.rgb2 = [1.0, 1.0, 1.0], [0.78, 0.82, 0.88]
    sky.width = sky.height = 64
    model = spec.compile()
    model.vis.headlight.ambient[:] = 0.35
    model.vis.headlight.diffuse[:] = 0.6
    data = mujoco.MjData(model)
    data.qpos[:] = request["qpos"]
    mujoco.mj_forward(model, data)
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, request["width"])
    model.vis.global_.offheight = max(model.vis.global_.offheight, request["height"])
    with mujoco.Renderer(model, request["height"], request["width"]) as renderer:
        renderer.update_scene(data, camera=_camera(model, data))
        image = renderer.render()
    sys.stdout.buffer.write(encode_png(image))
    sys.stdout.buffer.flush()
    return 0


if __name__ == "__main__":
    sys.exit(_child())
