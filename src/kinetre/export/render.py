"""Offscreen rendering of a deforming mesh on a shadowed ground plane, with OpenGL on the CPU.

Why this renderer: moderngl (PyPI wheel) opens a headless OpenGL 4.5 context through EGL on Mesa's
llvmpipe (Debian `libegl1`, `libgl1-mesa-dri`): no display, no GPU, no browser, one process, and pixels
come back with one glReadPixels straight into the ffmpeg pipe. Alternatives weighed: three.js in headless
Chromium (SwiftShader WebGL driven over the DevTools protocol: a browser process, a page, an npm bundle,
and a PNG screenshot encoded and decoded per frame: more moving parts and slower on the same software
rasteriser); pyrender (unmaintained, pins an old PyOpenGL); a numpy rasteriser (shadows and antialiasing
would be ours to write). Measured on the 2-core machine while ~6 other jobs ran (load average ~9), whole
`write_video` including skinning and H.264 encoding: spot (5.9k triangles) 6 fps, armadillo (86k) 3.7 fps,
the 772k-triangle elephant 3.1 fps through its 60k-triangle level of detail (`cluster_lod`).

Each frame the mesh is skinned on the CPU in float32 (`SkinTable`, Eq. 2; llvmpipe runs vertex
shaders on one thread, so skinning in the shader was slower) and drawn twice: into a 1024² shadow map
from the key light, then with 4x MSAA into the frame.

Picture: a fixed three-quarter camera framing the whole take, a key light from above-front-left whose
shadow (hardware-compared, bilinear PCF) falls on a checkered ground plane at the lowest point of the take
and fades into the sky, a hemisphere fill light; the mesh is shaded with its texture (UVs + material
image), its vertex colours or a neutral clay colour, in linear light with an sRGB output.
"""
from __future__ import annotations

import numpy as np

from ..errors import ExportError

_MESH_VS = """
#version 330
uniform mat4 view_proj;
in vec3 in_pos; in vec3 in_normal; in vec2 in_uv; in vec4 in_color;
out vec3 v_pos; out vec3 v_normal; out vec2 v_uv; out vec4 v_color;
void main() {
    v_pos = in_pos; v_normal = in_normal; v_uv = in_uv; v_color = in_color;
    gl_Position = view_proj * vec4(in_pos, 1.0);
}
"""

_MESH_FS = """
#version 330
uniform vec3 light_dir; uniform vec3 eye; uniform mat4 light_view_proj;
uniform sampler2DShadow shadow_map; uniform sampler2D albedo_map; uniform bool use_texture;
in vec3 v_pos; in vec3 v_normal; in vec2 v_uv; in vec4 v_color;
out vec4 frag;
float shadow(vec3 p, float bias) {
    // one hardware-compared, bilinearly filtered lookup: a 2x2 PCF for the price of one fetch
    vec4 q = light_view_proj * vec4(p, 1.0);
    vec3 s = q.xyz / q.w * 0.5 + 0.5;
    if (s.x < 0.0 || s.x > 1.0 || s.y < 0.0 || s.y > 1.0 || s.z > 1.0) return 1.0;
    return texture(shadow_map, vec3(s.xy, s.z - bias));
}
void main() {
    vec3 n = normalize(v_normal);
    vec3 view = normalize(eye - v_pos);
    if (dot(n, view) < 0.0) n = -n;                  // open meshes: light the inside too
    vec3 base = v_color.rgb;                          // colours and textures are sRGB: light in linear
    if (use_texture) base *= texture(albedo_map, v_uv).rgb;
    base = pow(base, vec3(2.2));
    float diffuse = max(dot(n, light_dir), 0.0) * shadow(v_pos, 0.002);
    float hemi = 0.5 + 0.5 * n.y;
    vec3 h = normalize(light_dir + view);
    float spec = pow(max(dot(n, h), 0.0), 40.0) * 0.15 * diffuse;
    vec3 c = base * (0.3 + 0.25 * hemi + 0.9 * diffuse) + vec3(spec);
    frag = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
}
"""

_DEPTH_FS = """
#version 330
void main() {}
"""

_GROUND_VS = """
#version 330
uniform mat4 view_proj;
in vec3 in_pos;
out vec3 v_pos;
void main() { v_pos = in_pos; gl_Position = view_proj * vec4(in_pos, 1.0); }
"""

_GROUND_FS = """
#version 330
uniform mat4 light_view_proj; uniform sampler2DShadow shadow_map; uniform vec3 centre; uniform float extent;
uniform float tile; uniform vec3 sky;
in vec3 v_pos;
out vec4 frag;
void main() {
    vec4 q = light_view_proj * vec4(v_pos, 1.0);
    vec3 s = q.xyz / q.w * 0.5 + 0.5;
    float lit = 1.0;
    if (s.x > 0.0 && s.x < 1.0 && s.y > 0.0 && s.y < 1.0 && s.z < 1.0) {
        // four filtered lookups 1.5 texels apart: a soft 4x4-texel penumbra
        vec2 d = 0.75 / vec2(textureSize(shadow_map, 0));
        lit = 0.25 * (texture(shadow_map, vec3(s.xy + vec2(-d.x, -d.y), s.z - 0.003))
                    + texture(shadow_map, vec3(s.xy + vec2(d.x, -d.y), s.z - 0.003))
                    + texture(shadow_map, vec3(s.xy + vec2(-d.x, d.y), s.z - 0.003))
                    + texture(shadow_map, vec3(s.xy + vec2(d.x, d.y), s.z - 0.003)));
    }
    vec2 cell = floor((v_pos.xz - centre.xz) / tile);
    float checker = mod(cell.x + cell.y, 2.0) * 0.04;
    vec3 c = pow(vec3(0.80 + checker), vec3(2.2)) * (0.45 + 0.55 * lit);
    float fade = smoothstep(0.55 * extent, extent, length(v_pos.xz - centre.xz));
    frag = vec4(mix(pow(c, vec3(1.0 / 2.2)), sky, fade), 1.0);
}
"""

SKY = (0.93, 0.95, 0.98)
CLAY = (0.78, 0.62, 0.50)


def look_at(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """(4, 4) view matrix (OpenGL convention: camera looks down -z)."""
    eye, target, up = (np.asarray(x, dtype=np.float64) for x in (eye, target, up))
    f = target - eye
    f /= np.linalg.norm(f)
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / np.tan(np.deg2rad(fov_y_deg) / 2)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = f / aspect, f
    m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def orthographic(half_w: float, half_h: float, near: float, far: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 0], m[1, 1] = 1 / half_w, 1 / half_h
    m[2, 2], m[2, 3] = -2 / (far - near), -(far + near) / (far - near)
    return m


def cluster_lod(vertices: np.ndarray, faces: np.ndarray, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """A lighter mesh for drawing: vertex clustering on a uniform grid (Rossignac & Borrel 1993).

    A 640x480 frame has 0.3 M pixels, so a mesh with more triangles than that only costs the CPU
    rasteriser time. Every vertex is snapped to the first vertex of its grid cell and faces that collapse
    are dropped; the kept vertices are original ones, so they are skinned exactly like the full mesh.

    Parameters
    ----------
    vertices : (V, 3) float, faces : (F, 3) int
    max_faces : int
        Triangle budget; the grid is refined until the result fits it.

    Returns
    -------
    keep : (K,) int64
        Indices of the original vertices drawn.
    lod_faces : (F', 3) int32
        Faces indexing into `keep`; F' <= max_faces. `faces` itself when F <= max_faces.
    """
    faces = np.asarray(faces)
    if len(faces) <= max_faces:
        return np.arange(len(vertices)), faces.astype(np.int32)
    lo = vertices.min(axis=0)
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    cell = np.sqrt(2.0 * area / max_faces)          # a closed surface keeps ~2 triangles per occupied cell
    for _ in range(20):
        ijk = np.floor((vertices - lo) / cell).astype(np.int64)
        dims = ijk.max(axis=0) + 1
        key = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]     # one integer per cell: fast unique
        _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
        f = inverse.reshape(-1)[faces]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
        srt = np.sort(f, axis=1)
        n = len(first)
        f = f[np.unique((srt[:, 0] * n + srt[:, 1]) * n + srt[:, 2], return_index=True)[1]]
        if len(f) <= max_faces:
            return first.astype(np.int64), f.astype(np.int32)
        cell *= 1.25
    return first.astype(np.int64), f[:max_faces].astype(np.int32)


class Camera:
    """A fixed three-quarter view framing a bounding box, and the key light's shadow projection.

    Attributes
    ----------
    view_proj, light_view_proj : (4, 4) float64
    eye, light_dir : (3,) float64
    ground : float
        Height of the ground plane (the lowest point of the take).
    centre : (3,) float64 and extent : float
        Centre of the take on the ground and the ground disc's radius.
    """

    def __init__(self, lo: np.ndarray, hi: np.ndarray, size: tuple[int, int], azimuth: float = 30.0,
                 elevation: float = 18.0, fov: float = 35.0):
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        centre = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-9)
        az, el = np.deg2rad(azimuth), np.deg2rad(elevation)
        direction = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
        aspect = size[0] / size[1]
        half_fov = np.deg2rad(fov) / 2
        fit = min(half_fov, np.arctan(np.tan(half_fov) * aspect))   # the narrower of the two view angles
        distance = 1.08 * radius / np.sin(fit)
        self.eye = centre + distance * direction
        near = max(distance - 4 * radius, 0.02 * distance)
        self.view_proj = perspective(fov, aspect, near, distance + 6 * radius) @ look_at(self.eye, centre)
        self.ground = float(lo[1])
        self.centre = np.array([centre[0], self.ground, centre[2]])
        self.extent = 3.0 * radius
        self.tile = radius / 3.0
        self.light_dir = np.array([-0.45, 1.0, 0.55]) / np.linalg.norm([-0.45, 1.0, 0.55])
        light_eye = centre + 4 * radius * self.light_dir
        self.light_view_proj = orthographic(1.6 * radius, 1.6 * radius, 0.5 * radius, 8 * radius) @ look_at(
            light_eye, centre, up=(0.0, 0.0, -1.0))

    def project(self, points: np.ndarray, size: tuple[int, int]) -> np.ndarray:
        """(P, 3) world points -> (P, 2) pixel coordinates (x right, y down)."""
        h = np.c_[points, np.ones(len(points))] @ self.view_proj.T
        ndc = h[:, :2] / h[:, 3:4]
        return np.c_[(ndc[:, 0] + 1) * 0.5 * size[0], (1 - ndc[:, 1]) * 0.5 * size[1]]


class MeshRenderer:
    """Renders frames of one deforming mesh; create once per video, call `render(positions, normals)`
    per frame. Faces, UVs, colours and the texture are uploaded once; per frame only the deformed
    positions and normals change."""

    def __init__(self, vertex_count: int, faces, camera: Camera, size=(640, 480), uvs=None, colors=None,
                 texture=None, shadow_size: int = 1024, samples: int = 4):
        try:
            import moderngl
        except ImportError as err:
            raise ExportError(f"video export needs moderngl (pip install moderngl): {err}") from None
        try:
            self.ctx = moderngl.create_standalone_context(backend="egl")
        except Exception as err:  # no EGL / Mesa: say which packages give it
            raise ExportError("video export cannot open a headless OpenGL context through EGL "
                              f"(install Debian libegl1 and libgl1-mesa-dri): {err}") from None
        ctx = self.ctx
        self.size = tuple(int(s) for s in size)
        self.camera = camera
        v = self.vertex_count = int(vertex_count)

        def buf(a, dtype):
            return ctx.buffer(np.ascontiguousarray(a, dtype=dtype).tobytes())

        color = np.tile(np.array([*CLAY, 1.0], np.float32), (v, 1)) if colors is None else \
            np.asarray(colors, np.float32) / 255.0
        uv = np.zeros((v, 2), np.float32) if uvs is None else np.asarray(uvs, np.float32)
        self._mesh_prog = ctx.program(vertex_shader=_MESH_VS, fragment_shader=_MESH_FS)
        self._depth_prog = ctx.program(vertex_shader=_MESH_VS, fragment_shader=_DEPTH_FS)
        self._positions = ctx.buffer(reserve=12 * v, dynamic=True)
        self._normals = ctx.buffer(reserve=12 * v, dynamic=True)
        content = [(self._positions, "3f", "in_pos"), (self._normals, "3f", "in_normal"),
                   (buf(uv, "f4"), "2f", "in_uv"), (buf(color, "f4"), "4f", "in_color")]
        index = buf(faces, "i4")

        def vao(prog):
            used = [c for c in content if c[2] in prog]    # the depth pass drops unused attributes
            return ctx.vertex_array(prog, used, index_buffer=index, index_element_size=4)

        self._mesh_vao = vao(self._mesh_prog)
        self._depth_vao = vao(self._depth_prog)

        c, e = camera.centre, camera.extent
        quad = np.array([[c[0] - e, c[1], c[2] - e], [c[0] + e, c[1], c[2] - e], [c[0] + e, c[1], c[2] + e],
                         [c[0] - e, c[1], c[2] - e], [c[0] + e, c[1], c[2] + e], [c[0] - e, c[1], c[2] + e]])
        self._ground_prog = ctx.program(vertex_shader=_GROUND_VS, fragment_shader=_GROUND_FS)
        self._ground_vao = ctx.vertex_array(self._ground_prog, [(buf(quad, "f4"), "3f", "in_pos")])

        self._shadow_tex = ctx.depth_texture((shadow_size, shadow_size))
        self._shadow_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._shadow_tex.repeat_x = self._shadow_tex.repeat_y = False
        self._shadow_tex.compare_func = "<="    # sampler2DShadow: compared and bilinearly filtered in hardware
        self._shadow_fbo = ctx.framebuffer(depth_attachment=self._shadow_tex)

        self._albedo = ctx.texture(texture.size, 3, np.asarray(texture.convert("RGB"))[::-1].tobytes()) \
            if texture is not None and uvs is not None else ctx.texture((1, 1), 3, bytes([255, 255, 255]))
        self._albedo.build_mipmaps()
        self._albedo.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)

        samples = samples if ctx.max_samples >= samples else 0
        self._msaa = ctx.framebuffer(color_attachments=[ctx.renderbuffer(self.size, 4, samples=samples)],
                                     depth_attachment=ctx.depth_renderbuffer(self.size, samples=samples))
        self._out = ctx.framebuffer(color_attachments=[ctx.renderbuffer(self.size, 4)])

        f4 = lambda m: np.ascontiguousarray(m.T, dtype=np.float32).tobytes()  # column-major for GLSL
        self._depth_prog["view_proj"].write(f4(camera.light_view_proj))
        mp = self._mesh_prog
        mp["view_proj"].write(f4(camera.view_proj))
        mp["light_view_proj"].write(f4(camera.light_view_proj))
        mp["light_dir"].value = tuple(camera.light_dir)
        mp["eye"].value = tuple(camera.eye)
        mp["shadow_map"].value = 1
        mp["albedo_map"].value = 2
        mp["use_texture"].value = texture is not None and uvs is not None
        gp = self._ground_prog
        gp["view_proj"].write(f4(camera.view_proj))
        gp["light_view_proj"].write(f4(camera.light_view_proj))
        gp["shadow_map"].value = 1
        gp["centre"].value = tuple(camera.centre)
        gp["extent"].value = float(camera.extent)
        gp["tile"].value = float(camera.tile)
        gp["sky"].value = SKY

    def render(self, positions: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """One frame.

        Parameters
        ----------
        positions, normals : (V, 3) float
            The deformed vertices and their normals (any length: normalised per pixel).

        Returns
        -------
        (H, W, 3) uint8 RGB image, top row first.
        """
        import moderngl

        ctx = self.ctx
        self._positions.write(np.ascontiguousarray(positions, dtype=np.float32).tobytes())
        self._normals.write(np.ascontiguousarray(normals, dtype=np.float32).tobytes())
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)

        self._shadow_fbo.use()
        self._shadow_fbo.clear(depth=1.0)
        self._depth_vao.render(moderngl.TRIANGLES)

        self._msaa.use()
        self._msaa.clear(*SKY, 1.0, depth=1.0)
        self._shadow_tex.use(1)
        self._albedo.use(2)
        self._ground_vao.render(moderngl.TRIANGLES)
        self._mesh_vao.render(moderngl.TRIANGLES)

        ctx.copy_framebuffer(self._out, self._msaa)
        data = self._out.read(components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(self.size[1], self.size[0], 3)[::-1]

    def release(self) -> None:
        self.ctx.release()
