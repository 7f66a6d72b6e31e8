import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.priors import PriorDatabase
from mmlearn.systems.articulation.prior_selector import PriorModelSelector, ShiftedLinkModel


def _arc(center, r, a0, a1, n, z=0.7):
    a = np.linspace(a0, a1, n)
    return np.c_[center[0] + r * np.cos(a), center[1] + r * np.sin(a), np.full(n, z)]


def _line(start, d, length, n):
    return np.asarray(start) + np.outer(np.linspace(0, length, n), d)


@pytest.fixture(scope="module")
def db():
    rng = np.random.default_rng(0)
    d = PriorDatabase(obs=ObservationModel(sigma_pos=0.01))
    for k in range(3):  # a door seen three times from different stopping places
        off = rng.uniform(-0.2, 0.2, 3) * [1, 1, 0]
        d.add(_arc((0, 0), 0.4, 0.0, 1.4, 60) + off + rng.normal(0, 0.002, (60, 3)), f"door{k}")
    for k in range(3):  # a drawer
        off = rng.uniform(-0.2, 0.2, 3) * [1, 1, 0]
        d.add(_line((0.5, 0.5, 0.8), (1, 0, 0), 0.45, 50) + off
              + rng.normal(0, 0.002, (50, 3)), f"drawer{k}")
    assert d.model_names() == ["revolute", "prismatic"]
    return d


def test_shifted_model_moves_positions_only(db):
    m = db.clusters[0].model
    o = np.array([1.0, -2.0, 0.5])
    s = ShiftedLinkModel(m, o)
    q = np.array([[0.3], [0.9]])
    np.testing.assert_allclose(s.forward(q)[:, :3], m.forward(q)[:, :3] + o)
    np.testing.assert_allclose(s.inverse(s.forward(q)), m.inverse(m.forward(q)), atol=1e-9)
    np.testing.assert_allclose(s.jacobian(q), m.jacobian(q))
    np.testing.assert_allclose(s.center, m.center + o)
    assert s.name == "revolute" and s.radius == pytest.approx(m.radius)


class _Replay(LeafSystem):
    def __init__(self, P, period):
        super().__init__()
        self._P, self._T = P, period
        self.DeclareVectorOutputPort("p", BasicVector(3), self._calc)

    def _calc(self, context, out):
        k = int(context.get_time() / self._T + 1e-6)
        out.SetFromVector(self._P[k] if k < len(self._P) else np.full(3, np.nan))


@pytest.mark.parametrize("kind,expect", [("door", (0, "revolute")), ("drawer", (1, "prismatic")),
                                         ("unknown", (-1, None))])
def test_selector_recognises_a_known_mechanism_early(db, kind, expect):
    off = np.array([3.0, 1.0, 0.0])  # a new stopping place
    if kind == "door":
        P = _arc((0, 0), 0.4, 0.0, 0.3, 15) + off       # 17 deg seen so far
    elif kind == "drawer":
        P = _line((0.5, 0.5, 0.8), (1, 0, 0), 0.08, 15) + off
    else:  # a long swing of a much larger radius than any known door
        P = _arc((0, 0), 1.5, 0.0, 0.6, 40) + off
    b = DiagramBuilder()
    src = b.AddSystem(_Replay(P, 0.03))
    sel = b.AddSystem(PriorModelSelector(db=db, period=0.03, every=5))
    b.Connect(src.get_output_port(), sel.get_hook_position_input_port())
    d = b.Build()
    ctx = d.CreateDefaultContext()
    sctx = sel.GetMyMutableContextFromRoot(ctx)
    sel.get_object_model_input_port().FixValue(sctx, None)
    Simulator(d, ctx).AdvanceTo(0.03 * len(P) + 0.1)
    cluster = int(sel.GetOutputPort("prior_cluster").Eval(sctx)[0])
    obj = sel.GetOutputPort("object_model").Eval(sctx)
    assert cluster == expect[0]
    if expect[1] is None:
        assert obj is None  # passes the (here empty) scratch model through
    else:
        link = obj.edges[0].model
        assert link.name == expect[1]
        # the prior model predicts the rest of the motion from where this one started
        if kind == "door":
            assert link.radius == pytest.approx(0.4, abs=0.02)
            pred = link.forward(link.inverse(P[-1:]) + 0.5)[0, :3]
            true = _arc((0, 0), 0.4, 0.75, 0.75, 1)[0] + off
            assert np.linalg.norm(pred - true) < 0.03


def test_selector_rejects_an_empty_database():
    with pytest.raises(ValueError, match="clusters"):
        PriorModelSelector(db=PriorDatabase())
