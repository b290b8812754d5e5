"""bsrbench: reference reproduction of Bayesian sparse-representation 3D human pose estimation.

Babagholami-Mohamadabadi, Jourabloo, Zarghami, Kasaei, "A Bayesian Framework for Sparse
Representation-Based 3D Human Pose Estimation" (IEEE Signal Processing Letters, 2014).
"""

__version__ = "0.1.0"
