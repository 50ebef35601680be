"""The vessel and its maths: the paper's model (section II), frames and geodesy, thrusters, path
geometry and the paper's metrics. Pure functions over plain floats (and CasADi, in ``model_casadi``).
"""
