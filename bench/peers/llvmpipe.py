#!/usr/bin/env python3
"""Render a peer triangle file (SGSC, see crates/albatros/src/peer.rs) with Mesa's
llvmpipe, the CPU OpenGL driver, and time it the way `albatros bench` does.

The set-up (Debian's Mesa EGL and DRI packages, moderngl from PyPI) is in
bench/peers/README.md. The context is an EGL context on Mesa's software device with
no surface (glcontext's EGL backend); the script refuses to time anything but
llvmpipe.

Per frame, all inside the timed region:
  clear the 4x MSAA framebuffer (colour to the file's clear colour, depth to 1),
  one draw call of all triangles (vertex buffer uploaded once before the loop,
  depth test GL_LESS, no culling, no blending), resolve the MSAA framebuffer into a
  single-sample one (glBlitFramebuffer), read the resolved RGBA8 image back into
  host memory (glReadPixels), glFinish.
Frames run after a warm-up; the median, minimum and maximum are reported.

Usage:
  llvmpipe.py FILE [--frames N] [--warmup N] [--threads N] [--png out.png]
              [--gamma G] [--scene NAME] [--json]
"""

import argparse
import json
import os
import statistics
import struct
import sys
import time
import zlib

MAGIC = b"SGSC"
HEADER = struct.Struct("<4s7I")  # magic, version, width, height, msaa, N, flags, clear
FLOATS_PER_VERTEX = 7
VERTEX_BYTES = FLOATS_PER_VERTEX * 4

VERTEX_SHADER = """
#version 330 core
in vec4 in_pos;
in vec3 in_color;
out vec3 v_color;
void main() {
    gl_Position = in_pos;
    v_color = in_color;
}
"""

FRAGMENT_SHADER = """
#version 330 core
in vec3 v_color;
out vec4 f_color;
void main() {
    f_color = vec4(v_color, 1.0);
}
"""

MESA_EGL_VENDOR = "/usr/share/glvnd/egl_vendor.d/50_mesa.json"


class PeerError(Exception):
    """A problem worth one clear line on stderr and exit status 1."""


def read_file(path):
    """The header fields and the vertex bytes of a triangle file, checked."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise PeerError(f"reading {path}: {e.strerror}") from e
    if len(data) < HEADER.size:
        raise PeerError(f"{path}: {len(data)} bytes is shorter than the 32-byte header")
    magic, version, width, height, msaa, n, flags, clear = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise PeerError(f"{path}: not a triangle file (magic {magic!r}, expected {MAGIC!r})")
    if version != 1:
        raise PeerError(f"{path}: version {version} is not supported (expected 1)")
    expected = HEADER.size + 3 * n * VERTEX_BYTES
    if len(data) != expected:
        raise PeerError(f"{path}: {n} triangles need {expected} bytes, the file has {len(data)}")
    if width == 0 or height == 0:
        raise PeerError(f"{path}: empty image {width}x{height}")
    rgba = tuple(((clear >> (8 * i)) & 0xFF) / 255.0 for i in range(4))
    return {
        "width": width,
        "height": height,
        "msaa": msaa,
        "triangles": n,
        "flags": flags,
        "clear": rgba,
        "vertices": memoryview(data)[HEADER.size:],
    }


def prefer_software_mesa(threads):
    """Environment for Mesa's software device, set before the context exists."""
    os.environ.setdefault("LIBGL_ALWAYS_SOFTWARE", "1")
    os.environ.setdefault("GALLIUM_DRIVER", "llvmpipe")
    if os.path.exists(MESA_EGL_VENDOR):
        # With glvnd, load Mesa's EGL even where another vendor (a GPU driver) is installed.
        os.environ.setdefault("__EGL_VENDOR_LIBRARY_FILENAMES", MESA_EGL_VENDOR)
    if threads is not None:
        os.environ["LP_NUM_THREADS"] = str(threads)


def write_png(path, width, height, rgb_rows_top_down):
    """A minimal RGB8 PNG writer (zlib + struct), so the peer needs no imaging library."""
    def chunk(kind, payload):
        body = kind + payload
        return struct.pack(">I", len(payload)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    raw = b"".join(b"\x00" + row for row in rgb_rows_top_down)
    png = (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw, 6))
        + chunk(b"IEND", b"")
    )
    try:
        with open(path, "wb") as f:
            f.write(png)
    except OSError as e:
        raise PeerError(f"writing {path}: {e.strerror}") from e


def run(args):
    scene = read_file(args.file)
    width, height, n = scene["width"], scene["height"], scene["triangles"]
    prefer_software_mesa(args.threads)
    try:
        import moderngl
    except ImportError as e:
        raise PeerError("moderngl is not installed: pip install moderngl (see bench/peers/README.md)") from e
    try:
        ctx = moderngl.create_context(standalone=True, backend="egl", require=330)
    except Exception as e:  # glcontext raises plain Exceptions with EGL's error
        raise PeerError(f"no EGL OpenGL 3.3 context: {e} (see bench/peers/README.md)") from e
    renderer = ctx.info["GL_RENDERER"]
    version = ctx.info["GL_VERSION"]
    print(f"GL_RENDERER: {renderer}\nGL_VERSION:  {version}", file=sys.stderr)
    if "llvmpipe" not in renderer and not args.any_renderer:
        raise PeerError(f"the renderer is '{renderer}', not llvmpipe (--any-renderer to time it anyway)")
    samples = scene["msaa"] or 1
    if samples > ctx.max_samples:
        raise PeerError(f"{samples}x MSAA asked for, the driver's maximum is {ctx.max_samples}")

    prog = ctx.program(vertex_shader=VERTEX_SHADER, fragment_shader=FRAGMENT_SHADER)
    vbo = ctx.buffer(scene["vertices"])  # uploaded once
    vao = ctx.vertex_array(prog, [(vbo, "4f 3f", "in_pos", "in_color")])
    msaa_fbo = ctx.framebuffer(
        color_attachments=[ctx.renderbuffer((width, height), 4, samples=samples)],
        depth_attachment=ctx.depth_renderbuffer((width, height), samples=samples),
    )
    resolved = ctx.framebuffer(color_attachments=[ctx.renderbuffer((width, height), 4)])
    readback = bytearray(width * height * 4)
    ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
    ctx.enable(moderngl.DEPTH_TEST)
    ctx.depth_func = "<"
    r, g, b, a = scene["clear"]

    def frame():
        msaa_fbo.use()
        msaa_fbo.clear(r, g, b, a, depth=1.0)
        vao.render(moderngl.TRIANGLES, vertices=3 * n)
        ctx.copy_framebuffer(resolved, msaa_fbo)  # the MSAA resolve
        resolved.read_into(readback, components=4)
        ctx.finish()

    for _ in range(args.warmup):
        frame()
    times = []
    for _ in range(args.frames):
        t0 = time.perf_counter()
        frame()
        times.append((time.perf_counter() - t0) * 1000.0)
    err = ctx.error
    if err != "GL_NO_ERROR":
        raise PeerError(f"OpenGL error: {err}")

    if args.png:
        rgb = resolved.read(components=3, alignment=1)
        lut = bytes(round(255.0 * (i / 255.0) ** (1.0 / args.gamma)) for i in range(256))
        stride = 3 * width
        # OpenGL's rows start at the bottom: flip them for the PNG.
        rows = [rgb[y * stride:(y + 1) * stride].translate(lut) for y in range(height - 1, -1, -1)]
        write_png(args.png, width, height, rows)
        print(f"image: {args.png}", file=sys.stderr)

    result = {
        "peer": "llvmpipe",
        "scene": args.scene or os.path.splitext(os.path.basename(args.file))[0],
        "width": width,
        "height": height,
        "triangles": n,
        "msaa": samples,
        "frames": len(times),
        "warmup": args.warmup,
        "median_ms": round(statistics.median(times), 3),
        "min_ms": round(min(times), 3),
        "max_ms": round(max(times), 3),
        "renderer": renderer,
        "threads": int(os.environ["LP_NUM_THREADS"]) if "LP_NUM_THREADS" in os.environ else None,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"{result['scene']}: {width}x{height}, {n} triangles, {samples}x MSAA on {renderer}\n"
            f"  {len(times)} frames after {args.warmup} warm-up: median {result['median_ms']:.2f} ms "
            f"(min {result['min_ms']:.2f}, max {result['max_ms']:.2f}), "
            f"{1000.0 / result['median_ms']:.1f} frames/s"
        )


def main():
    parser = argparse.ArgumentParser(
        description="Render an Albatros peer triangle file (SGSC) with Mesa llvmpipe and time it."
    )
    parser.add_argument("file", help="triangle file written by `albatros dump SCENE --format triangles`")
    parser.add_argument("--frames", type=int, default=20, help="timed frames (default 20)")
    parser.add_argument("--warmup", type=int, default=3, help="untimed frames first (default 3)")
    parser.add_argument("--threads", type=int, help="llvmpipe rasterizer threads (LP_NUM_THREADS; default: all CPUs)")
    parser.add_argument("--png", help="also save the resolved image as a PNG (rows flipped to top-down)")
    parser.add_argument(
        "--gamma", type=float, default=2.2, help="display gamma applied to the PNG only (default 2.2, as albatros render)"
    )
    parser.add_argument("--scene", help="scene name for the JSON (default: the file's name)")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument("--any-renderer", action="store_true", help="time whatever renderer EGL gives, not only llvmpipe")
    args = parser.parse_args()
    if args.frames < 1 or args.warmup < 0:
        parser.error("--frames must be at least 1 and --warmup at least 0")
    if not args.gamma > 0:
        parser.error("--gamma must be positive")
    if args.threads is not None and args.threads < 0:
        parser.error("--threads must be 0 or more")
    try:
        run(args)
    except PeerError as e:
        print(f"llvmpipe.py: {e}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
