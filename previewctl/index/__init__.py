"""The avoidance index: AMSI (eqs. 3-17, and their planar closed form), the obstacle potential, AMSIP
(eq. 18), and loading a robot (which computes its structural ranks with the AMSI)."""
