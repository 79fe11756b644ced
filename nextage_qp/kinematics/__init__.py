"""Forward kinematics and Jacobians of any frame, and the reference chains they are checked against (DH, Nextage)."""
