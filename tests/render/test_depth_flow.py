"""Depth and dense correspondence (issue 38), proved by rendering: the rendered depth against the
painting plane's own depth, the flow it gives against the homographies, and on an ellipsoid of a
static scene against ray casting the ellipsoid through both cameras."""

import numpy as np
import pytest
import torch

from sidar_torch import SidarDataset, flow, geometry
from sidar_torch.sample.correspondence import DEPTH_EDGE
from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.render.meshes import unit_primitive
from sidar_torch.scene import Camera, Light, Material, Occluder, SceneSequence, ViewScene

from conftest import SMALL, WHITE, small_config, textured_painting

pytestmark = pytest.mark.gl


def pixel_grid(size):
    """``(3, H W)`` float64 homogeneous pixel centres, row by row (Kornia pixels)."""
    v, u = np.meshgrid(np.arange(size[0], dtype=float), np.arange(size[1], dtype=float), indexing="ij")
    return np.stack([u.ravel(), v.ravel(), np.ones(u.size)])


def rays(K, R, t, size):
    """Camera centre ``(3,)`` and world directions ``(3, H W)`` through every pixel centre."""
    return -R.T @ t, R.T @ np.linalg.solve(K, pixel_grid(size))


def plane_depth(K, R, t, size):
    """``(H W,)`` the camera-frame z of the painting plane (world z = 0) at every pixel centre."""
    centre, directions = rays(K, R, t, size)
    distance = -centre[2] / directions[2]  # along directions whose camera z is 1
    return distance


def project(K, R, t, points):
    """``(2, N)`` pixels of world ``points`` ``(3, N)``."""
    x = K @ (R @ points + t[:, None])
    return x[:2] / x[2]


def painting_around(painting, landed):
    """``(N,)`` bool: the 3 x 3 pixels around the pixel nearest to each point ``landed`` ``(2, N)`` lie
    inside the image and all show the painting (``painting`` ``(H, W)`` bool; NaN: nowhere)."""
    H, W = painting.shape
    col, row = np.round(np.nan_to_num(landed, nan=-10.0)).astype(int)
    inside = (col >= 1) & (col <= W - 2) & (row >= 1) & (row <= H - 2)
    col, row = np.where(inside, col, 1), np.where(inside, row, 1)
    around = np.ones_like(inside)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            around &= painting[row + dy, col + dx]
    return inside & around


def as_sample(depth, K, R, t):
    """The keys :func:`sidar_torch.flow` reads, as a sample dict holds them."""
    return {"depth": torch.from_numpy(depth)[:, None], "K": torch.from_numpy(K).float(),
            "R": torch.from_numpy(R).float(), "t": torch.from_numpy(t).float()}


def test_painting_depth_is_the_planes_and_its_flow_is_the_homography():
    dataset = SidarDataset(config=small_config("parallax"), seed=3)
    for index in range(2):
        sample = dataset.sample(index)
        K, R, t = (sample[k].double().numpy() for k in "KRt")
        depth, masks = sample["depth"][:, 0].double().numpy(), sample["masks"][:, 0].numpy() == 0
        n_views, (H, W) = len(depth), SMALL
        pixels = pixel_grid(SMALL)
        for i in range(n_views):
            truth = plane_depth(K[i], R[i], t[i], SMALL).reshape(H, W)
            painting = masks[i]
            assert painting.sum() > 500
            assert np.abs(depth[i][painting] / truth[painting] - 1).max() < 1e-4
            for j in range(n_views):
                if i == j:
                    continue
                f, valid = flow(sample, i, j)
                f, valid = f.double().numpy().reshape(2, -1), valid[0].numpy().ravel()
                mapped = sample["homographies"][i, j].double().numpy() @ pixels
                expected = mapped[:2] / mapped[2] - pixels[:2]
                on = valid & painting.ravel()
                assert on.sum() > 200, (i, j)
                assert np.abs(f[:, on] - expected[:, on]).max() < 1e-3, (i, j)
                # Painting points that land well inside view j on its painting, away from anything
                # else, are valid: the validity test does not throw away what it should keep.
                landed = np.where(mapped[2] > 0, mapped[:2] / mapped[2], -10)
                clear = painting_around(masks[j], landed)
                expect_valid = clear & painting.ravel()
                assert valid[expect_valid].mean() > 0.99, (i, j)


def test_the_flow_output_is_each_views_flow_to_view_0_nan_where_not_valid():
    # float64 cameras in the sample: the output is computed from the renderer's (float64) cameras.
    config = small_config("parallax", flow_output=True, geometry_dtype="float64")
    sample = SidarDataset(config=config, seed=5).sample(1)
    flows = sample["flow_to_reference"]
    assert flows.shape == (3, 2, *SMALL) and flows.dtype == torch.float32
    for i in range(3):
        expected, valid = flow(sample, i, 0)
        torch.testing.assert_close(flows[i], expected.where(valid, torch.tensor(float("nan"))), rtol=0, atol=0,
                                   equal_nan=True)
        assert valid.float().mean() > 0.2
    without = SidarDataset(config=config.replace(flow_output=False, depth_output=False), seed=5).sample(1)
    assert "depth" not in without and "flow_to_reference" not in without
    assert torch.equal(without["images"], sample["images"]) and torch.equal(without["masks"], sample["masks"])
    only_flow = SidarDataset(config=config.replace(depth_output=False), seed=5).sample(1)
    assert "depth" not in only_flow  # drawn for the flow, not handed out
    torch.testing.assert_close(only_flow["flow_to_reference"], flows, rtol=0, atol=0, equal_nan=True)


def test_forward_backward_flow_on_the_painting_closes_within_a_hundredth_of_a_pixel():
    # The way back starts at sub-pixel points of view j, so it is read from view j's rendered depth
    # there (inverse depth interpolated bilinearly: exact on a plane; the flow field itself is not
    # bilinear, 0.016 px off between these cameras), lifted and projected into view i.
    sample = SidarDataset(config=small_config("parallax"), seed=4).sample(0)
    K, R, t = (sample[k].double().numpy() for k in "KRt")
    depth, painting = sample["depth"][:, 0].double().numpy(), sample["masks"][:, 0].numpy() == 0
    H, W = SMALL
    for i, j in ((0, 1), (1, 2), (2, 0), (1, 0)):
        forward, valid = flow(sample, i, j)
        landed = pixel_grid(SMALL)[:2] + forward.double().numpy().reshape(2, -1)
        keep = valid[0].numpy().ravel() & painting[i].ravel() & painting_around(painting[j], landed)
        x, y = landed[:, keep]
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - x0, y - y0
        inverse = 1 / depth[j]
        interpolated = ((1 - fy) * ((1 - fx) * inverse[y0, x0] + fx * inverse[y0, x0 + 1])
                        + fy * ((1 - fx) * inverse[y0 + 1, x0] + fx * inverse[y0 + 1, x0 + 1]))
        centre, _ = rays(K[j], R[j], t[j], SIZE)
        directions = R[j].T @ np.linalg.solve(K[j], np.stack([x, y, np.ones_like(x)]))
        back = project(K[i], R[i], t[i], centre[:, None] + directions / interpolated)
        error = np.linalg.norm(back - pixel_grid(SMALL)[:2, keep], axis=0)
        assert keep.sum() > 500, (i, j)
        assert error.max() < 0.01, (i, j, error.max())


# --------------------------------------------------------------------------- an ellipsoid in a static scene

SIZE = (120, 160)
ELLIPSOID = Occluder("sphere", np.array([0.04, -0.03, 0.28]), geometry.look_at(np.array([0.3, 0.4, 0.5]))[0],
                     np.array([0.14, 0.09, 0.11]), Material(np.array([0.8, 0.3, 0.2, 1.0]), 0.0, 0.6))
CAMERAS = [Camera(*geometry.reference_camera(SIZE, 0.9)),
           Camera(geometry.intrinsics_from_fov(70, SIZE), *geometry.look_at(np.array([0.35, -0.25, 0.8]))),
           Camera(geometry.intrinsics_from_fov(80, SIZE), *geometry.look_at(np.array([-0.3, 0.3, 0.75])))]


def ellipsoid_hits(centre, directions, scale=1.0):
    """Ray parameter ``(N,)`` of the first hit of rays ``centre + s directions`` on the analytic
    surface of :data:`ELLIPSOID` grown by ``scale`` (NaN: missed)."""
    to_world = ELLIPSOID.object_to_world()
    inverse = np.linalg.inv(to_world[:3, :3] * scale)
    o = inverse @ (centre - to_world[:3, 3])
    d = inverse @ directions
    a, b, c = (d * d).sum(0), 2 * (o[:, None] * d).sum(0), o @ o - 1
    disc = b * b - 4 * a * c
    return np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.nan)


def mesh_hits(centre, directions):
    """Ray parameter ``(N,)`` of the first hit of rays ``centre + s directions`` on the triangles the
    renderer draws for :data:`ELLIPSOID` (its fixed mesh, posed; Moller-Trumbore), NaN where they miss,
    and the cosine between each ray and the hit triangle's normal (small: grazing)."""
    mesh = unit_primitive(ELLIPSOID.shape)
    to_world = ELLIPSOID.object_to_world()
    triangles = (mesh.vertices[mesh.faces] @ to_world[:3, :3].T) + to_world[:3, 3]  # (F, 3, 3)
    a, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    normals = np.cross(e1, e2)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    best, cosine = np.full(directions.shape[1], np.nan), np.zeros(directions.shape[1])
    for start in range(0, directions.shape[1], 512):
        d = directions[:, start:start + 512].T[:, None]  # (n, 1, 3)
        p = np.cross(d, e2)
        det = (p * e1).sum(-1)
        safe = np.where(np.abs(det) > 1e-12, det, np.inf)
        q = centre - a
        u = (p * q).sum(-1) / safe
        qe = np.cross(q, e1)
        v = (d * qe).sum(-1) / safe
        s = (qe * e2).sum(-1) / safe
        s = np.where((u >= 0) & (v >= 0) & (u + v <= 1) & (s > 0) & np.isfinite(safe), s, np.inf)
        first = s.argmin(1)
        hit = s[np.arange(len(s)), first]
        best[start:start + 512] = np.where(np.isfinite(hit), hit, np.nan)
        cosine[start:start + 512] = np.abs((d[:, 0] * normals[first]).sum(-1)) / np.linalg.norm(d[:, 0], axis=-1)
    return best, cosine


@pytest.fixture(scope="module")
def static_scene():
    light = Light("spot", np.array([[0.2, 0.1, 2.0]]), np.ones(3), 6.0, 0.9, 1.0)
    sequence = SceneSequence(SIZE, tuple(ViewScene(camera, (light,), (ELLIPSOID,), WHITE, 0.3) for camera in CAMERAS))
    renderer = shared_renderer(RenderSettings(SIZE, outputs=frozenset({"depth"})))
    rendered = renderer.render(sequence, textured_painting(SIZE))
    K, R, t = sequence.cameras()
    return rendered, as_sample(rendered.outputs["depth"], K, R, t), (K, R, t)


def test_flow_from_an_ellipsoid_lands_on_the_same_surface_point_in_the_other_view(static_scene):
    _, sample, (K, R, t) = static_scene
    depth = sample["depth"][:, 0].double().numpy()
    checked = 0
    for i, j in ((0, 1), (1, 0), (1, 2), (2, 0)):
        centre, directions = rays(K[i], R[i], t[i], SIZE)
        s, cosine = mesh_hits(centre, directions)
        occluder = np.isfinite(s) & (s < plane_depth(K[i], R[i], t[i], SIZE)) & (cosine > 0.3)
        f, valid = flow(sample, i, j)
        keep = occluder & valid[0].numpy().ravel() & (depth[i].ravel() < plane_depth(K[i], R[i], t[i], SIZE) * 0.999)
        points = centre[:, None] + s[keep] * directions[:, keep]
        expected = project(K[j], R[j], t[j], points)
        landed = pixel_grid(SIZE)[:2, keep] + f.double().numpy().reshape(2, -1)[:, keep]
        assert keep.sum() > 100, (i, j)
        assert np.abs(landed - expected).max() < 0.05, (i, j, np.abs(landed - expected).max())
        # Parallax: the ellipsoid does not move as the painting's homography says.
        H = geometry.plane_induced_homographies(K, R, t)[i, j]
        mapped = H @ pixel_grid(SIZE)[:, keep]
        assert np.median(np.linalg.norm(mapped[:2] / mapped[2] - expected, axis=0)) > 3, (i, j)
        checked += keep.sum()
    assert checked > 1000


def test_painting_points_the_ellipsoid_hides_from_the_other_camera_are_invalid_the_others_valid(static_scene):
    rendered, sample, (K, R, t) = static_scene
    H, W = SIZE
    for i, j in ((0, 1), (0, 2), (1, 2), (2, 1)):
        centre_i, directions = rays(K[i], R[i], t[i], SIZE)
        z = plane_depth(K[i], R[i], t[i], SIZE)
        painting_seen = ~rendered.masks[i].ravel()
        points = centre_i[:, None] + z * directions  # on the plane
        centre_j = -R[j].T @ t[j]
        towards = points - centre_j[:, None]  # from camera j: hidden if the ellipsoid is hit before s = 1
        landed = project(K[j], R[j], t[j], points)
        inside = (landed[0] >= 1) & (landed[0] <= W - 2) & (landed[1] >= 1) & (landed[1] <= H - 2)
        hidden = [np.isfinite(s) & (s > 0) & (s < 1) for s in (ellipsoid_hits(centre_j, towards, grow)
                                                               for grow in (0.97, 1.05))]
        _, valid = flow(sample, i, j)
        valid = valid[0].numpy().ravel()
        surely_hidden = painting_seen & inside & hidden[0]
        surely_seen = painting_seen & inside & ~hidden[1] & painting_around(~rendered.masks[j], landed)
        assert surely_hidden.sum() > 30, (i, j)
        assert not valid[surely_hidden].any(), (i, j)
        assert valid[surely_seen].mean() > 0.99, (i, j)


def test_valid_pixels_land_where_view_j_sees_the_same_depth(static_scene):
    _, sample, (K, R, t) = static_scene
    depth = sample["depth"][:, 0].double().numpy()
    H, W = SIZE
    for i, j in ((0, 1), (1, 2), (2, 0)):
        f, valid = flow(sample, i, j)
        keep = valid[0].numpy().ravel()
        centre, directions = rays(K[i], R[i], t[i], SIZE)
        points = centre[:, None] + depth[i].ravel()[keep] * directions[:, keep]
        z_j = (R[j] @ points + t[j][:, None])[2]
        landed = pixel_grid(SIZE)[:2, keep] + f.double().numpy().reshape(2, -1)[:, keep]
        nearest = depth[j][np.round(landed[1]).astype(int), np.round(landed[0]).astype(int)]
        assert np.abs(nearest / z_j - 1).max() < DEPTH_EDGE, (i, j)


def test_the_depth_pass_changes_no_other_pixel(static_scene):
    rendered, _, _ = static_scene
    light = Light("spot", np.array([[0.2, 0.1, 2.0]]), np.ones(3), 6.0, 0.9, 1.0)
    sequence = SceneSequence(SIZE, tuple(ViewScene(camera, (light,), (ELLIPSOID,), WHITE, 0.3) for camera in CAMERAS))
    without = shared_renderer(RenderSettings(SIZE)).render(sequence, textured_painting(SIZE))
    assert np.array_equal(without.views, rendered.views) and np.array_equal(without.masks, rendered.masks)
    assert np.array_equal(without.label, rendered.label) and set(rendered.outputs) == {"depth"}
    depth = rendered.outputs["depth"]
    assert depth.dtype == np.float32 and np.array_equal(np.isinf(depth), rendered.background)  # inf: nothing drawn
