"""The Drake side of tactile sensing: taxel integration, TactileSensor, the switching grasp
controller of Eq. 7.8 and the container physics (thesis ch. 6-7)."""

import numpy as np
import pytest

from mmlearn.models.tactile.containers import (CONTAINER_CLASSES, sample_container, states_of)
from mmlearn.models.tactile.pad import (PAD_CH6, PAD_PR2, PadLayout, integrate_pressure,
                                        integrate_pressure_pads, sensor_reading,
                                        subdivision_points)


# ------------------------------------------------------------------ pad integration (numpy)
def _sliver_fan(layout, n=60, z=0.0):
    """Triangles covering the pad rectangle as a fan of slivers from one corner (each spans
    many cells)."""
    w, L = layout.width / 2, layout.length / 2
    apex = np.array([-w, L, z])
    edge = np.concatenate([np.column_stack([np.full(n, w), np.linspace(L, -L, n), np.full(n, z)]),
                           np.column_stack([np.linspace(w, -w, n), np.full(n, -L), np.full(n, z)])])
    tris = [[apex, edge[i], edge[i + 1]] for i in range(len(edge) - 1)]
    return np.array(tris)


def test_subdivision_points_are_centroids_of_equal_subtriangles():
    for n in (1, 2, 5):
        B = subdivision_points(n)
        assert B.shape == (n * n, 3)
        assert np.allclose(B.sum(axis=1), 1.0) and (B > 0).all()
        assert np.allclose(B.mean(axis=0), 1 / 3)  # symmetric tiling


@pytest.mark.parametrize("layout", [PAD_CH6, PAD_PR2])
def test_uniform_pressure_on_slivers_gives_uniform_cells(layout):
    tri = _sliver_fan(layout)
    p = np.full((len(tri), 3), 1.0e5)
    cells = integrate_pressure(layout, tri, p)
    assert cells.shape == (layout.rows, layout.cols)
    # every cell carries pressure x its own area, although each sliver spans many cells
    assert np.allclose(cells, 1.0e5, rtol=0.06), cells / 1e5
    total = cells.sum() * layout.cell_area
    assert total == pytest.approx(1.0e5 * layout.length * layout.width, rel=1e-9)


def test_linear_pressure_field_cell_means():
    lay = PAD_CH6
    tri = _sliver_fan(lay, n=40)
    # p = a + b * y (linear): each cell's mean is the value at its centre row
    a, b = 1.0e5, 2.0e6
    p = a + b * tri[..., 1]
    cells = integrate_pressure(lay, tri, p)
    row_y = lay.length / 2 - (np.arange(lay.rows) + 0.5) * lay.length / lay.rows
    expect = np.repeat((a + b * row_y)[:, None], lay.cols, axis=1)
    assert np.allclose(cells, expect, rtol=0.06)
    assert cells[0].mean() > cells[-1].mean()  # row 0 at +y_P


def test_outside_pad_and_far_from_plane_are_ignored_and_bad_faces_skipped():
    lay = PAD_PR2
    tri = _sliver_fan(lay) + np.array([1.0, 0.0, 0.0])  # shifted off the pad
    assert integrate_pressure(lay, tri, np.full((len(tri), 3), 1e5)).sum() == 0
    tri = _sliver_fan(lay, z=0.02)  # 2 cm above the pad plane: another part of the finger
    assert integrate_pressure(lay, tri, np.full((len(tri), 3), 1e5)).sum() == 0
    tri = _sliver_fan(lay)
    p = np.full((len(tri), 3), 1e5)
    p[0, 0] = np.nan
    assert np.isfinite(integrate_pressure(lay, tri, p)).all()
    assert integrate_pressure(lay, np.zeros((0, 3, 3)), np.zeros((0, 3))).sum() == 0


def test_exact_integration_matches_fine_sampling_and_single_cell_values():
    """The clipped integral equals a 40 000-point quadrature binned by cell (random
    triangles and linear pressures, partly off the pad), and known cases exactly."""
    rng = np.random.default_rng(3)
    for lay in (PAD_CH6, PAD_PR2):
        n = 30
        tri = np.stack([rng.uniform(-0.6, 0.6, (n, 3)) * lay.width,
                        rng.uniform(-0.6, 0.6, (n, 3)) * lay.length,
                        rng.normal(0.0, 1e-4, (n, 3))], axis=2)
        p = rng.uniform(0.0, 2e5, (n, 3))
        got = integrate_pressure(lay, tri, p)
        B = subdivision_points(200)
        pts = np.einsum("sk,nkd->nsd", B, tri)
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        az = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        f = (p @ B.T) * az[:, None] / B.shape[0]
        cw, ch = lay.width / lay.cols, lay.length / lay.rows
        u = np.floor((pts[..., 0] + lay.width / 2) / cw).astype(int)
        v = np.floor((lay.length / 2 - pts[..., 1]) / ch).astype(int)
        m = (u >= 0) & (u < lay.cols) & (v >= 0) & (v < lay.rows)
        ref = np.bincount(v[m] * lay.cols + u[m], weights=f[m],
                          minlength=lay.rows * lay.cols).reshape(lay.rows, lay.cols)
        ref /= lay.cell_area
        assert np.abs(got - ref).max() < 2e-3 * ref.max()
        # several pads in one pass give each pad's own result
        both = integrate_pressure_pads(lay, [tri, tri[:0], tri[::2]], [p, p[:0], p[::2]])
        assert both.shape == (3, lay.rows, lay.cols)
        assert np.allclose(both[0], got) and not both[1].any()
        assert np.allclose(both[2], integrate_pressure(lay, tri[::2], p[::2]))
    # uniform pressure on slivers: every cell exactly (the sampling method was 6 % off)
    for lay in (PAD_CH6, PAD_PR2):
        tri = _sliver_fan(lay)
        cells = integrate_pressure(lay, tri, np.full((len(tri), 3), 1.0e5))
        assert np.allclose(cells, 1.0e5, rtol=1e-9)
    # one triangle = the lower-left half of cell (row 0, col 0), clockwise, p linear in x
    lay = PAD_PR2
    cw, ch = lay.width / lay.cols, lay.length / lay.rows
    x0, y0 = -lay.width / 2, lay.length / 2
    tri = np.array([[[x0, y0, 0.0], [x0, y0 - ch, 0.0], [x0 + cw, y0 - ch, 0.0]]])
    p = np.array([[0.0, 0.0, 3.0e5]])  # mean over the triangle 1e5, over the cell 0.5e5
    cells = integrate_pressure(lay, tri, p)
    assert cells[0, 0] == pytest.approx(0.5e5, rel=1e-12)
    assert np.count_nonzero(cells) == 1
    # a triangle on the border of two cells goes to the cell it covers only
    tri2 = tri + np.array([cw, 0.0, 0.0])
    tri2[0, 0, 0] = tri2[0, 1, 0] = x0 + cw  # left edge exactly on the grid line
    cells = integrate_pressure(lay, tri2, np.full((1, 3), 1e5))
    assert cells[0, 1] == pytest.approx(0.5e5, rel=1e-12) and cells.sum() == cells[0, 1]


def test_edges_on_cell_borders_are_counted_once():
    """Triangles with vertices on a quarter-cell lattice (edges along cell borders and the
    pad border, as a box pad pressed on a flat block gives): the cells carry exactly the
    triangles' area, and no cell more than its own (an edge on a border counted twice
    once gave a cell +60 %)."""
    rng = np.random.default_rng(0)
    for lay in (PAD_CH6, PAD_PR2):
        cw, ch = lay.width / lay.cols, lay.length / lay.rows
        for _ in range(40):
            n = 20
            x = rng.integers(0, 4 * lay.cols + 1, (n, 3)) / 4.0 * cw - lay.width / 2
            y = lay.length / 2 - rng.integers(0, 4 * lay.rows + 1, (n, 3)) / 4.0 * ch
            tri = np.stack([x, y, np.zeros_like(x)], axis=2)
            e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
            areas = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
            cells = integrate_pressure(lay, tri, np.ones((n, 3)))
            assert cells.sum() * lay.cell_area == pytest.approx(areas.sum(), rel=1e-9, abs=1e-15)
            for j in np.flatnonzero(areas > 0)[:5]:
                one = integrate_pressure(lay, tri[j:j + 1], np.ones((1, 3)))
                assert one.max() <= 1.0 + 1e-9
                assert one.sum() * lay.cell_area == pytest.approx(areas[j], rel=1e-9)
    # a sliver of a real contact surface (PR2 pad on a flat block) whose long edge lies on
    # the pad border to round-off (x = 0.009 and 0.008999999999999998): its force is tiny
    tri = np.array([[[0.008962716696934603, -0.000755260036321509, -3.73e-05],
                     [0.009, -0.0007999999999999952, -3.73e-05],
                     [0.008999999999999998, -0.01472037522700953, -3.73e-05]]])
    p = np.array([[18641.651532698423, 0.0, 9.313225746154785e-10]])
    e1, e2 = tri[0, 1] - tri[0, 0], tri[0, 2] - tri[0, 0]
    force = 0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0]) * p.mean()  # 1.6 mN
    got = integrate_pressure(PAD_PR2, tri, p).sum() * PAD_PR2.cell_area
    assert got == pytest.approx(force, rel=1e-6)


def test_sensor_reading_saturates_and_is_seeded():
    lay = PAD_PR2
    c = np.full((lay.rows, lay.cols), 2 * lay.p_sat)
    assert np.all(sensor_reading(lay, c, rng=np.random.default_rng(0)) == 1.0)
    c = np.full((lay.rows, lay.cols), 0.5 * lay.p_sat)
    r1 = sensor_reading(lay, c, rng=np.random.default_rng(1), noise=0.02)
    r2 = sensor_reading(lay, c, rng=np.random.default_rng(1), noise=0.02)
    assert np.array_equal(r1, r2) and abs(r1.mean() - 0.5) < 0.02
    with pytest.raises(ValueError, match="rows"):
        PadLayout(rows=0, cols=3, length=0.03, width=0.02, p_sat=1e5)


# ------------------------------------------------------------------ containers (numpy)
def test_container_stiffness_follows_state():
    rng = np.random.default_rng(0)
    k = {s: np.median([sample_container("odwalla", s, rng).k for _ in range(30)])
         for s in states_of("odwalla")}
    # closed full resists most (small headspace), then the closed air spring, then open
    assert k["full_closed"] > k["empty_closed"] > k["full_open"] > k["empty_open"]
    assert "empty_closed" not in states_of("can")  # cans cannot be closed again
    with pytest.raises(ValueError, match="impossible state"):
        sample_container("can", "empty_closed", rng)
    with pytest.raises(ValueError, match="unknown class"):
        sample_container("jar", "full_open", rng)
    full = sample_container("water", "full_open", rng)
    empty = sample_container("water", "empty_open", rng)
    assert full.mass > empty.mass + 0.3 and full.slosh_mass > 0 and empty.slosh_mass == 0
    assert set(CONTAINER_CLASSES) == {"odwalla", "naked", "can", "water"}


# ------------------------------------------------------------------ Drake: sensor + controller
def _contact_force_trace(cfg, object_sdf, t_end):
    from mmlearn.diagrams.tactile.grasp import simulate_contact_force

    _, F, sim, parts = simulate_contact_force(cfg, object_sdf=object_sdf, t_end=t_end)
    return F, sim, parts


@pytest.mark.slow
def test_flat_block_pressed_with_known_force_gives_expected_cells():
    from mmlearn.diagrams.tactile.grasp import TactileGraspConfig
    from mmlearn.sdf.tactile import block_sdf

    f = 30.0
    cfg = TactileGraspConfig(pad="ch6", f_target=f, taxel_noise=0.0, grasp_height=0.06,
                             hold_time=5.0, force_rate=150.0)
    F, sim, parts = _contact_force_trace(cfg, block_sdf((0.07, 0.1, 0.12)), 1.4)
    s = parts["sensor"]
    sc = s.GetMyContextFromRoot(sim.get_context())
    img = s.split(s.get_taxels_output_port().Eval(sc))
    lay = s.pads[0].layout
    expect = f / (lay.length * lay.width) / lay.p_sat  # the block covers the whole pad
    for side in ("left", "right"):
        assert img[side].shape == (14, 6)
        assert np.allclose(img[side], expect, rtol=0.1), img[side] / expect
    assert np.allclose(img["left"], img["right"][:, ::-1], atol=0.01 * expect + 1e-3)
    assert np.allclose(s.get_pad_force_output_port().Eval(sc), f, rtol=0.01)
    assert F[-1] == pytest.approx(f, rel=0.01)


@pytest.mark.slow
def test_switching_controller_has_no_impact_spike_pure_force_has():
    from mmlearn.diagrams.tactile.grasp import TactileGraspConfig
    from mmlearn.sdf.tactile import block_sdf

    block = block_sdf((0.07, 0.1, 0.12))  # rigid: the wooden block of Fig. 7.5 / 7.6
    peaks = {}
    for mode in ("switching", "force"):
        cfg = TactileGraspConfig(pad="pr2", f_target=10.0, mode=mode, taxel_noise=0.0,
                                 hold_time=5.0)
        F, _, _ = _contact_force_trace(cfg, block, 1.3)
        assert F[-1] == pytest.approx(10.0, rel=0.02)
        peaks[mode] = F.max()
    assert peaks["switching"] <= 10.0 * 1.03, peaks  # no overshoot beyond 3 %
    assert peaks["force"] > 10.0 * 1.2, peaks  # the pure force controller's impact spike


@pytest.mark.slow
def test_self_centring_palm_makes_p_first_independent_of_placement():
    """A container placed 2 mm off-centre: with the welded palm the first finger squeezes the
    flimsy wall alone until the second finger touches (p_first several mm short of the
    centred grasp); with the self-centring palm slide p_first is the centred one."""
    from mmlearn.diagrams.tactile.grasp import (PALM_SLIDE_DAMPING, TactileGraspConfig,
                                                simulate_grasp)
    from mmlearn.models.tactile.state import extract_grasp_features

    inst = sample_container("water", "empty_open", np.random.default_rng(3))

    def p_first(offset, slide):
        cfg = TactileGraspConfig(pad="pr2", f_target=20.0, duration=1.7, hold_time=1.0,
                                 offset=offset, seed=1, taxel_noise=0.0, encoder_noise=0.0,
                                 palm_slide_damping=slide)
        ft = extract_grasp_features(simulate_grasp(cfg, container=inst), contact_force=1.0,
                                    rest_velocity=0.002)
        assert ft.contact
        return ft.values[0]

    centred = p_first(0.0, PALM_SLIDE_DAMPING)
    assert 2 * inst.radius - 0.008 < centred < 2 * inst.radius
    assert abs(p_first(0.002, PALM_SLIDE_DAMPING) - centred) < 5e-4
    assert p_first(0.002, None) < centred - 0.005  # the welded palm's one-sided squeeze
    with pytest.raises(ValueError, match="palm_slide_damping"):
        simulate_grasp(TactileGraspConfig(palm_slide_damping=-1.0))


def test_grasp_of_nothing_is_no_contact():
    from mmlearn.diagrams.tactile.grasp import TactileGraspConfig, simulate_grasp
    from mmlearn.models.tactile.state import extract_grasp_features

    g = simulate_grasp(TactileGraspConfig(duration=1.0, v_target=0.1))
    assert g.f.max() < 1.0 and g.p[-1] < 0.01
    ft = extract_grasp_features(g, contact_force=1.0, rest_velocity=0.002)
    assert not ft.contact


def test_bad_arguments_are_named():
    from mmlearn.systems.tactile.grasp_controller import TactileGraspController
    from mmlearn.systems.tactile.sensor import TactileSensor

    with pytest.raises(ValueError, match="mode"):
        TactileGraspController(f_target=10.0, mode="crush")
    with pytest.raises(ValueError, match="f_target"):
        TactileGraspController(f_target=float("nan"))
    with pytest.raises(ValueError, match="no pads"):
        TactileSensor(pads=[])


def test_wrist_force_sensor_sees_the_fingers_weight():
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.tactile.grasp import MakeTactileGraspDiagram, TactileGraspConfig

    cfg = TactileGraspConfig(duration=0.2)
    d, parts = MakeTactileGraspDiagram(cfg)
    sim = Simulator(d)
    sim.Initialize()
    sim.AdvanceTo(0.2)
    w = parts["wrist_force_sensor"]
    f = w.get_force_output_port().Eval(w.GetMyContextFromRoot(sim.get_context()))
    # the two fingers (cfg.gripper.finger_mass each) hang on the palm
    assert f[2] == pytest.approx(-2 * cfg.gripper.finger_mass * 9.81, abs=0.2)


class _FakeMeshcat:
    """Records the calls a visualiser makes."""

    def shown(self, cell):
        """The colour (r, g, b, a) of the level box of ``cell`` that is visible, and its time."""
        on = [(path, t) for (path, prop), (v, t) in self.props.items()
              if prop == "visible" and path.rsplit("/", 1)[0] == cell and v]
        assert len(on) == 1, on
        c = self.objects[on[0][0]][1]
        return np.array([c.r(), c.g(), c.b(), c.a()]), on[0][1]

    def __init__(self):
        self.objects, self.transforms, self.props = {}, {}, {}

    def SetObject(self, path, shape, rgba):
        self.objects[path] = (shape, rgba)

    def SetTransform(self, path, X, time_in_recording=None):
        self.transforms[path] = (X, time_in_recording)

    def SetProperty(self, path, prop, value, time_in_recording=None):
        self.props[(path, prop)] = (value, time_in_recording)


def test_taxel_visualizer_colours_cells_by_reading_at_the_pad():
    from pydrake.math import RigidTransform

    from mmlearn.systems.tactile.taxel_visualizer import TaxelPadVisualizer, taxel_colors
    from mmlearn.systems.tactile.sensor import PadSpec

    assert np.allclose(taxel_colors([0.0, 1.0, np.nan])[:, :3],
                       [[0, 0, 0.5], [0.5, 0, 0], [0, 0, 0.5]])
    lay = PAD_PR2
    pads = [PadSpec("left", lay, 1, RigidTransform([0.0, 0.0, 0.1]), ()),
            PadSpec("right", lay, 1, RigidTransform([0.0, 0.0, -0.1]), ())]
    mc = _FakeMeshcat()
    vis = TaxelPadVisualizer(meshcat=mc, pads=pads, display_depth=0.01, bar_height=0.004)
    assert len(mc.objects) == 2 * lay.rows * lay.cols * 5  # a box per cell and colour level
    ctx = vis.CreateDefaultContext()
    x = np.zeros(2 * lay.rows * lay.cols)
    x[0] = 1.0  # left pad, row 0 (fingertip), column 0 saturated
    x[lay.rows * lay.cols + 7] = 0.5
    vis.get_taxels_input_port().FixValue(ctx, x)
    vis.get_body_poses_input_port().FixValue(ctx, [RigidTransform(), RigidTransform([1.0, 0, 0])])
    ctx.SetTime(0.4)
    vis.ForcedPublish(ctx)
    X, t = mc.transforms["taxels/left"]
    assert t == 0.4 and np.allclose(X.translation(), [1.0, 0.0, 0.09])  # body, pad, -depth
    hot, t = mc.shown("taxels/left/r00c00")
    assert np.allclose(hot, [0.5, 0.0, 0.0, 1.0]) and t == 0.4
    assert np.allclose(mc.shown("taxels/left/r00c01")[0], [0, 0, 0.5, 1])
    assert mc.props[("taxels/left/r00c00", "scale")][0][2] == pytest.approx(0.004)
    X0 = mc.transforms["taxels/left/r00c00"][0].translation()  # cell centre in the pad
    assert np.allclose(X0[:2], [-lay.width / 2 + lay.width / 6, lay.length / 2 - lay.length / 10])
    r, c = divmod(7, lay.cols)
    mid = mc.shown(f"taxels/right/r{r:02d}c{c:02d}")[0]
    assert np.allclose(mid[:3], [0.5, 1.0, 0.5])
    # a wrong-sized vector is refused at the port, not inside the running display
    with pytest.raises(Exception):
        vis.get_taxels_input_port().FixValue(ctx, np.zeros(3))
    with pytest.raises(ValueError, match="no pads"):
        TaxelPadVisualizer(meshcat=mc, pads=[])


def test_taxel_visualizer_redraws_a_recording_on_a_fitted_scale():
    from pydrake.math import RigidTransform

    from mmlearn.systems.tactile.sensor import PadSpec
    from mmlearn.systems.tactile.taxel_visualizer import TaxelPadVisualizer

    lay = PAD_PR2
    n = lay.rows * lay.cols
    mc = _FakeMeshcat()
    vis = TaxelPadVisualizer(meshcat=mc, pads=[PadSpec("left", lay, 1, RigidTransform(), ())])
    R = np.zeros((2, n))
    R[1, 0], R[1, 1] = 0.27, 0.135  # a firm grasp reads far below saturation
    assert vis.recolor_recording([0.0, 0.04], R) == pytest.approx(0.3)  # 0.27 rounded up
    hot, t = mc.shown("taxels/left/r00c00")
    assert t == pytest.approx(0.04) and hot[0] >= 0.5 and hot[2] < 0.1  # red, not blue
    assert np.allclose(mc.shown("taxels/left/r00c01")[0][:3], [0.5, 1.0, 0.5])  # half: green
    assert mc.props[("taxels/left/r00c00", "scale")][0][2] > 0.8 * 0.004
    assert vis.recolor_recording([0.0, 0.04], R, full_scale=1.0) == 1.0
    assert mc.shown("taxels/left/r00c00")[0][2] > 0.5  # on the sensor's scale: blue
    with pytest.raises(ValueError, match="columns"):
        vis.recolor_recording([0.0], np.zeros((1, 3)))
    with pytest.raises(ValueError, match="full_scale"):
        TaxelPadVisualizer(meshcat=mc, pads=[PadSpec("left", lay, 1, RigidTransform(), ())],
                           full_scale=0.0)
