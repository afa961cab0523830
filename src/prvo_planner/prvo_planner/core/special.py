"""
scipy.special's normal-distribution functions, imported on their first call.

Importing scipy.special costs a process 0.2-0.5 s of CPU (its array-API layer imports
numpy.testing and numpy.f2py). Every ROS node imports ``prvo_planner.core``, most never call
these: the runner, the stand-ins, a planner without walls or close neighbours. Each function
here is scipy's own ufunc, called with the same arguments, so every result is the same to the bit.
"""


def ndtr(x):
    """Return ``scipy.special.ndtr(x)``, the standard normal distribution function."""
    from scipy.special import ndtr as scipy_ndtr
    return scipy_ndtr(x)


def ndtri(p):
    """Return ``scipy.special.ndtri(p)``, the inverse of `ndtr`."""
    from scipy.special import ndtri as scipy_ndtri
    return scipy_ndtri(p)


def erfcx(x):
    """Return ``scipy.special.erfcx(x)``, the scaled complementary error function."""
    from scipy.special import erfcx as scipy_erfcx
    return scipy_erfcx(x)
