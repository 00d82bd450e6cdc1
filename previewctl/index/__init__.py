"""The avoidance index: AMSI (eqs. 3-17), the obstacle potential, and AMSIP (eq. 18)."""
