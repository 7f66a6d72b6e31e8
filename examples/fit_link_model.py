"""Fit a link model to a numpy array of positions, without any Drake diagram (thesis ch. 4).

The "track" is what any sensor gives: an (n, 3) array of a handle's positions in the frame
of the fixed part (here simulated: 40 points on a 0.45 m circle over 70 deg with 5 mm
noise; an (n, 7) array of x y z qx qy qz qw poses works too). ``select_link_model`` fits
the candidate models (rigid, prismatic, revolute, Gaussian process) and keeps the one with
the lowest BIC; the ``ObservationModel`` tells it the noise. The selected model maps a
configuration q (rad or m) to a position or pose (``forward``) and back (``inverse``).

    python examples/fit_link_model.py
"""
import numpy as np

from mmlearn.models.articulation import ObservationModel, select_link_model

rng = np.random.default_rng(0)
q = np.linspace(0.0, np.radians(70), 40)
centre, radius = np.array([1.0, 0.5, 0.8]), 0.45
track = np.c_[centre[0] + radius * np.cos(q), centre[1] + radius * np.sin(q),
              np.full_like(q, centre[2])] + rng.normal(0.0, 0.005, (q.size, 3))

selection = select_link_model(track, obs=ObservationModel(sigma_pos=0.005), rng=0)
for name, bic in sorted(selection.bic.items(), key=lambda kv: kv[1]):
    print(f"{name:>9}: BIC {bic:9.1f}")
link = selection.best
print(f"selected {link.name}: radius {link.radius:.3f} m, centre {np.round(link.center, 3)}, "
      f"axis {np.round(link.axis, 2)}, seen over {np.degrees(link.q_max[0] - link.q_min[0]):.0f} deg")
# forward: (k, dof) configurations -> (k, 3) positions (a track of positions) or (k, 7) poses
print("handle at q = 0.5 rad:", np.round(link.forward(np.array([[0.5]]))[0], 3), "m")
