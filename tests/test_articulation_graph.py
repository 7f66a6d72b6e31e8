"""Kinematic graphs with loops, DOF estimation, incremental structure (thesis 4.2, 4.4.1, 4.4.3)."""

import numpy as np
import pytest

from mmlearn.diagrams.common.object_tracks import (cabinet_scenario, table_phases, table_scenario,
                                                   yardstick_scenario)
from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.graph import (KinematicGraphEvaluator, as_part_tracks,
                                               fit_pair_models, fit_structure, pca_projection,
                                               read_parts_csv, spanning_tree_edges,
                                               write_parts_csv)
from mmlearn.models.articulation.incremental import IncrementalStructure, incremental_structure
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common.se3 import relative_poses

OBS = ObservationModel(sigma_pos=0.005, sigma_orient=np.deg2rad(3))
PARAM = ("rigid", "prismatic", "revolute")


@pytest.fixture(scope="module")
def open_stick():
    tr = yardstick_scenario(False, 60, rng=3)
    return tr, fit_pair_models(tr.poses, obs=OBS, rng=3, models=PARAM + ("gp",))


@pytest.fixture(scope="module")
def closed_stick():
    tr = yardstick_scenario(True, 60, rng=4)
    return tr, fit_pair_models(tr.poses, obs=OBS, rng=4, models=PARAM + ("gp",))


def test_open_yardstick_three_dof_chain(open_stick):
    tr, pm = open_stick
    r = fit_structure(tr.poses, search="local", reduce_dofs=True, obs=OBS, pair_models=pm)
    assert r.best.dof == 3
    assert set(r.best.edges) == {(0, 1), (1, 2), (2, 3)}
    assert all(m == "revolute" for m in r.best.models.values())
    # PCA with fewer DOFs cannot explain three independent hinges: BIC rises steeply
    ev = KinematicGraphEvaluator(tr.poses, pm, obs=OBS)
    b = ev.evaluate(r.best.edges, reduce_dofs=True, reduce_tree_dofs=True).bic_per_dof
    assert min(b, key=b.get) == 3
    assert b[2] > b[3] + 1000 and b[0] > b[2]
    # optimised poses stay within the noise of the observations
    assert r.best.pos_error_m < 3 * 0.005 * np.sqrt(3)


def test_closed_yardstick_one_dof(closed_stick):
    tr, pm = closed_stick
    r = fit_structure(tr.poses, search="local", reduce_dofs=True, obs=OBS, pair_models=pm)
    assert r.best.dof == 1
    # the four revolute links of the loop (Fig. 4.16, right column)
    assert r.best.has_loop
    assert set(r.best.edges) == {(0, 1), (1, 2), (2, 3), (0, 3)}
    assert all(m == "revolute" for m in r.best.models.values())
    assert r.tree.dof == 3  # a tree's DOFs are the sum of its links' DOFs
    assert r.best.bic < r.tree.bic - 500  # never worse than the spanning tree
    # without DOF reduction the same graph needs D_links DOFs and is far worse
    ev = KinematicGraphEvaluator(tr.poses, pm, obs=OBS)
    full = ev.evaluate(r.best.edges)
    assert full.dof == full.dof_links >= 3
    assert full.bic > r.best.bic + 500


@pytest.mark.slow
def test_local_search_close_to_exhaustive(closed_stick):
    tr, pm = closed_stick
    loc = fit_structure(tr.poses, search="local", reduce_dofs=True, obs=OBS, pair_models=pm)
    exh = fit_structure(tr.poses, search="exhaustive", reduce_dofs=True, obs=OBS, pair_models=pm)
    assert len(exh.evaluated) == 38  # connected spanning subgraphs of K4
    assert len(loc.evaluated) < len(exh.evaluated) / 3
    assert exh.best.bic <= loc.best.bic <= loc.tree.bic
    assert (loc.best.bic - exh.best.bic) / abs(exh.best.bic) < 0.05
    assert exh.best.dof == 1
    # the "best" strategy evaluates whole neighbourhoods and ends at least as well
    best = fit_structure(tr.poses, search="local", reduce_dofs=True, obs=OBS, pair_models=pm)
    from mmlearn.models.articulation.graph import search_structure

    ev = KinematicGraphEvaluator(tr.poses, pm, obs=OBS)
    b2, _, order = search_structure(ev, loc.tree.edges, search="local", reduce_dofs=True,
                                    strategy="best")
    assert b2.bic <= best.best.bic + 1e-6 and len(order) >= len(loc.evaluated)
    with pytest.raises(ValueError, match="strategy"):
        search_structure(ev, loc.tree.edges, strategy="random")


def test_loop_graph_with_wrong_edge_is_worse(closed_stick):
    tr, pm = closed_stick
    ev = KinematicGraphEvaluator(tr.poses, pm, obs=OBS)
    loop = ev.evaluate([(0, 1), (1, 2), (2, 3), (0, 3)], reduce_dofs=True)
    assert loop.has_loop and loop.dof == 1
    # replace a revolute link by a rigid one between moving parts
    from mmlearn.models.articulation.link import make_model

    z = relative_poses(tr.poses[0], tr.poses[1])
    pm2 = dict(pm)
    pm2[(0, 1)] = make_model("rigid", obs=OBS).fit(z, rng=0)
    bad = KinematicGraphEvaluator(tr.poses, pm2, obs=OBS).evaluate(
        [(0, 1), (1, 2), (2, 3), (0, 3)], reduce_dofs=True)
    assert bad.bic > loop.bic + 1000


def test_pca_projection_recovers_linear_manifold():
    rng = np.random.default_rng(0)
    t = rng.uniform(0, 1, 100)
    Q = np.stack([t, np.pi - t, t, -t], axis=1) + rng.normal(0, 1e-3, (100, 4))
    Qh, P, mu, ratio = pca_projection(Q, 1)
    assert P.shape == (1, 4)
    assert ratio[0] > 0.999
    assert np.abs(Qh - Q).max() < 0.01


def test_graph_input_errors(open_stick):
    tr, pm = open_stick
    Y = tr.poses.copy()
    Y[1, 3, 2] = np.nan  # a partly NaN row
    with pytest.raises(ValueError, match="partly NaN"):
        as_part_tracks(Y)
    with pytest.raises(ValueError, match="position-only"):
        as_part_tracks([tr.poses[0][:, :3], tr.poses[1][:, :3]])
    with pytest.raises(ValueError, match="at least 2 parts"):
        as_part_tracks([tr.poses[0]])
    with pytest.raises(ValueError, match="time steps"):
        as_part_tracks([tr.poses[0], tr.poses[1][:10]])
    with pytest.raises(ValueError, match="unknown search"):
        fit_structure(tr.poses, search="greedy", pair_models=pm)
    ev = KinematicGraphEvaluator(tr.poses, pm, obs=OBS)
    with pytest.raises(ValueError, match="does not connect"):
        ev.evaluate([(0, 1), (2, 3)])
    with pytest.raises(ValueError, match="no link model"):
        KinematicGraphEvaluator(tr.poses, {(0, 1): pm[(0, 1)]}, obs=OBS).evaluate([(0, 2)])
    hidden = tr.poses.copy()
    hidden[0, 2:] = np.nan
    with pytest.raises(ValueError, match="observe every part"):
        KinematicGraphEvaluator(hidden, pm, obs=OBS)
    with pytest.raises(ValueError, match="cannot be connected"):
        spanning_tree_edges({(0, 1): pm[(0, 1)]}, 4)


def test_parts_csv_roundtrip_and_errors(tmp_path, open_stick):
    tr, _ = open_stick
    Y = tr.poses[:, :10].copy()
    Y[2, 4] = np.nan
    f = tmp_path / "obj.csv"
    write_parts_csv(f, tr.parts, np.arange(10) * 0.5, Y)
    names, t, Y2 = read_parts_csv(f)
    assert names == tr.parts and t.shape == (10,)
    assert np.isnan(Y2[2, 4]).all()
    ok = np.isfinite(Y2)
    assert np.allclose(Y2[ok], Y[ok], atol=1e-7)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,part,x,y,z,qx,qy,qz\n0,a,0,0,0,0,0,0\n")
    with pytest.raises(ValueError, match="bad header"):
        read_parts_csv(bad)
    bad.write_text("t,part,x,y,z,qx,qy,qz,qw\n0,a,0,0,0,0,0,0,1\n0,a,1,0,0,0,0,0,1\n")
    with pytest.raises(ValueError, match="observed twice"):
        read_parts_csv(bad)
    bad.write_text("t,part,x,y,z,qx,qy,qz,qw\n0,a,0,zero,0,0,0,0,1\n")
    with pytest.raises(ValueError, match=":2: non-numeric"):
        read_parts_csv(bad)
    with pytest.raises(FileNotFoundError):
        read_parts_csv(tmp_path / "missing.csv")


def test_cabinet_structure_changes_as_drawers_move():
    tr = cabinet_scenario(20, 30, rng=1)
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    hist = incremental_structure(tr.poses, tr.parts, refit_every=10, obs=obs, rng=1,
                                 models=PARAM)
    first = {s.n: s for s in hist}[20]
    # only the lower drawer moved: the upper drawer is rigid to the cabinet
    assert ("cabinet", "upper_drawer", "rigid") in first.edge_set()
    assert any(m == "prismatic" and "lower_drawer" in (a, b) for a, b, m in first.edges)
    assert first.dof == 1
    last = hist[-1]
    assert last.n == 50
    assert last.edge_set() == {("cabinet", "upper_drawer", "prismatic"),
                               ("cabinet", "lower_drawer", "prismatic")}
    assert last.dof == 2


def test_incremental_input_errors():
    inc = IncrementalStructure(["a", "b"], rng=0)
    with pytest.raises(ValueError, match=r"expected \(2, 7\)"):
        inc.add(np.zeros((3, 7)))
    with pytest.raises(ValueError, match="unknown search"):
        IncrementalStructure(["a", "b"], search="bfs")
    with pytest.raises(ValueError, match="at least 2 parts"):
        IncrementalStructure(["a"])


def test_table_on_the_floor_needs_a_two_dof_gp():
    tr = table_scenario(12, rng=2)
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    Z = relative_poses(tr.poses[0], tr.poses[1]).as_array()
    models = ("rigid", "prismatic", "gp", "gp2")
    still = select_link_model(Z[:12], models=models, obs=obs, rng=0)
    line = select_link_model(Z[:24], models=models, obs=obs, rng=0)
    free = select_link_model(Z, models=models, obs=obs, rng=0)
    assert still.selected == "rigid"
    assert line.selected == "prismatic"
    assert free.selected == "gp2"


def test_table_pushed_forward_then_sideways_selects_a_one_dof_gp():
    # Fig. 4.9 (c): after the sideways push, the 1-D path (line, quarter circle, sideways line)
    # is a curve that neither a prismatic nor a revolute joint explains; the table never turns.
    ph = table_phases(12)
    assert ph["still"] == ph["line"] == 12 and ph["free"] == 24
    assert ph["curve"] == round((np.pi / 2 + 1) * 11)  # constant speed: 0.8/11 m per sample
    tr = table_scenario(12, rng=2)
    assert tr.poses.shape[1] == sum(ph.values())
    end = ph["still"] + ph["line"] + ph["curve"]
    xy = tr.q[:end, :2]
    assert np.allclose(tr.q[:, 2], 0.0)
    assert np.allclose(np.linalg.norm(np.diff(xy[ph["still"]:], axis=0), axis=1), 0.8 / 11,
                       rtol=0.02)
    assert np.allclose(xy[end - 1], [1.6, 1.6])
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    Z = relative_poses(tr.poses[0], tr.poses[1]).as_array()
    curve = select_link_model(Z[:end], models=("rigid", "prismatic", "revolute", "gp", "gp2"),
                              obs=obs, rng=0)
    assert curve.selected == "gp"
    assert curve.bic["gp"] < min(curve.bic["prismatic"], curve.bic["revolute"], curve.bic["gp2"])
