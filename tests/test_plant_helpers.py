"""JointFriction: regularised Coulomb friction from the plant's state (systems/common/plant_helpers.py)."""

import numpy as np
import pytest

from mmlearn.systems import JointFriction


def test_joint_friction_output_is_regularised_coulomb_on_the_chosen_joints():
    sys = JointFriction(num_positions=3, num_velocities=3, joints={0: 2.0, 2: 0.5}, v_stiction=0.1)
    ctx = sys.CreateDefaultContext()
    v = np.array([0.05, 1.0, -3.0])
    sys.get_state_input_port().FixValue(ctx, np.concatenate([np.zeros(3), v]))
    tau = sys.get_generalized_force_output_port().Eval(ctx)
    np.testing.assert_allclose(tau, [-2.0 * np.tanh(0.5), 0.0, 0.5 * np.tanh(30.0)])
    assert sys.num_continuous_states() == 0 and sys.num_discrete_state_groups() == 0


@pytest.mark.parametrize("kw, msg", [({"v_stiction": 0.0}, "v_stiction"),
                                     ({"joints": {0: -1.0}}, "friction coefficients")])
def test_joint_friction_rejects_bad_parameters(kw, msg):
    args = dict(num_positions=1, num_velocities=1, joints={0: 1.0})
    args.update(kw)
    with pytest.raises(ValueError, match=msg):
        JointFriction(**args)
