"""The closed-form fast path for planar arms: chain data, vectorised kinematics and AMSI, distances, redundancy map."""
