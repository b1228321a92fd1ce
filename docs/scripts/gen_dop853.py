"""Write scara_gym/model/dop853.py: Dormand and Prince's 8(5,3) pair with its degree-7 dense
output, the tableau of Hairer's dop853.f as scipy.integrate.DOP853 carries it, its stages
written out with their nonzero coefficients (as the integrator's DOPRI5 stages are).

    python docs/scripts/gen_dop853.py            # rewrite the module
    python docs/scripts/gen_dop853.py --check    # exit 1 when the module is not what this writes

A test runs the check, so that the module cannot drift from scipy's coefficients.
"""

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as tableau

MODULE = Path(__file__).resolve().parents[2] / "scara_gym" / "model" / "dop853.py"
N_STAGES = tableau.N_STAGES  # 12; stage 12 is f(y_new), 13-15 the dense output's extra stages

HEADER = '''"""Dormand and Prince's 8(5,3) Runge-Kutta pair and its degree-7 dense output, compiled.

Written by ``docs/scripts/gen_dop853.py`` from the tableau of Hairer's dop853.f as
``scipy.integrate.DOP853`` carries it (E. Hairer, S. P. Norsett, G. Wanner, Solving Ordinary
Differential Equations I, 2nd ed., Springer 1993, section II.10); do not edit by hand. Stages,
error estimate and dense output are scipy's, term by term: ``stages`` fills k[1..12] (k[12] =
f(y_new), the next step's k[0]), ``error_norm`` is scipy's combined 5th/3rd-order estimate,
``dense_stages`` adds k[13..15] and the dense output's rows F, and ``state_at`` evaluates it.
``bernstein`` turns F into the degree-7 Bernstein coefficients of each state along the step,
which bound it (convex hull) for the integrator's switch search.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from scara_gym.model.compilation import JIT_INLINE
from scara_gym.model.dynamics import derivative

'''


def _array(name: str, values) -> list[str]:
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        return [f"{name} = np.array([{', '.join(repr(float(v)) for v in values)}])"]
    return [f"{name} = np.array(["] + ["    [" + ", ".join(repr(float(v)) for v in row) + "]," for row in values] + ["])"]


def _combination(row, stages: range, name: str = "k") -> str:
    terms = [f"{repr(float(row[j]))} * {name}[{j}, i]" for j in stages if row[j] != 0.0]
    return " + ".join(terms)


def _wrapped(text: str, indent: int) -> list[str]:
    """text split at ' + ' into lines of at most 110 characters (continued inside parentheses)."""
    lines, current = [], ""
    for part in text.split(" + "):
        candidate = part if not current else current + " + " + part
        if len(candidate) + indent > 104 and current:
            lines.append(current)
            current = "+ " + part
        else:
            current = candidate
    lines.append(current)
    return lines


def _assignment(target: str, base: str, row, stages: range, indent: int = 8) -> list[str]:
    parts = _wrapped(_combination(row, stages), indent + 4)
    first = f"{' ' * indent}{target} = {base} + h * ({parts[0]}"
    rest = [f"{' ' * (indent + 4)}{p}" for p in parts[1:]]
    lines = [first] + rest
    lines[-1] += ")"
    return lines


def module_text() -> str:
    out = HEADER.splitlines()
    out += _array("A", tableau.A) + _array("C", tableau.C) + _array("B", tableau.B)
    out += _array("E3", tableau.E3) + _array("E5", tableau.E5) + _array("D", tableau.D)
    out += ['"""the tableau (A rows 12: B, the stage f(y_new); rows 13-15: the dense output\'s extra stages)"""',
            "N_STAGES = 12", "DENSE_ROWS = 7  # rows of F: the dense output is a polynomial of degree 7 in theta",
            "ERROR_EXPONENT = -1.0 / 8.0  # the step factor's exponent: the estimate's order is 7", "", ""]
    out += ["def _bernstein_weights() -> np.ndarray:",
            '    """W[j, r]: the weight of F[r] in the j-th degree-7 Bernstein coefficient of state_at - x.',
            "    F[r] enters state_at multiplied by theta^a (1 - theta)^b, a = ceil((r + 1) / 2), b = floor((r + 1) / 2),",
            '    whose degree-7 Bernstein coefficients are C(7 - a - b, j - a) / C(7, j) for a <= j <= 7 - b."""',
            "    weights = np.zeros((8, 7))",
            "    for r in range(7):",
            "        a, b = (r + 2) // 2, (r + 1) // 2",
            "        for j in range(a, 8 - b):",
            "            weights[j, r] = math.comb(7 - a - b, j - a) / math.comb(7, j)",
            "    return weights", "", "",
            "BERNSTEIN_WEIGHTS = _bernstein_weights()", "", ""]
    # the stages
    out += ["@njit(**JIT_INLINE)",
            "def stages(x, h, k, y_stage, y_new, robot, p, config, volts):",
            '    """k[1..11] at the step\'s stages from k[0] = f(x), y_new, and k[12] = f(y_new): 12 right-hand sides."""',
            "    n = x.shape[0]"]
    for s in range(1, N_STAGES):
        out += ["    for i in range(n):"]
        out += _assignment("y_stage[i]", "x[i]", tableau.A[s], range(s))
        out += [f"    derivative(y_stage, robot, p, config, k[{s}], volts)"]
    out += ["    for i in range(n):"]
    out += _assignment("y_new[i]", "x[i]", tableau.B, range(N_STAGES))
    out += [f"    derivative(y_new, robot, p, config, k[{N_STAGES}], volts)", "", ""]
    # the error estimate
    e5 = _wrapped(_combination(tableau.E5, range(N_STAGES + 1)), 20)
    e3 = _wrapped(_combination(tableau.E3, range(N_STAGES + 1)), 20)
    out += ["@njit(**JIT_INLINE)",
            "def error_norm(x, y_new, h, k, rtol, atol):",
            '    """scipy\'s DOP853 error norm: |h| |e5|^2 / sqrt((|e5|^2 + 0.01 |e3|^2) n), scaled by atol + rtol max(|x|, |y_new|)."""',
            "    n = x.shape[0]",
            "    total5 = 0.0",
            "    total3 = 0.0",
            "    for i in range(n):",
            "        scale = atol + rtol * max(abs(x[i]), abs(y_new[i]))",
            f"        e5 = ({e5[0]}"] + [f"              {p}" for p in e5[1:]]
    out[-1] += ") / scale"
    out += [f"        e3 = ({e3[0]}"] + [f"              {p}" for p in e3[1:]]
    out[-1] += ") / scale"
    out += ["        total5 += e5 * e5",
            "        total3 += e3 * e3",
            "    if total5 == 0.0 and total3 == 0.0:",
            "        return 0.0",
            "    return abs(h) * total5 / math.sqrt((total5 + 0.01 * total3) * n)", "", ""]
    # the dense output
    out += ["@njit(**JIT_INLINE)",
            "def dense_stages(x, y_new, h, k, y_stage, robot, p, config, volts, f):",
            '    """k[13..15] (3 right-hand sides) and the dense output\'s rows f[0..6] (scipy\'s F)."""',
            "    n = x.shape[0]"]
    for s in range(N_STAGES + 1, N_STAGES + 4):
        out += ["    for i in range(n):"]
        out += _assignment("y_stage[i]", "x[i]", tableau.A[s], range(s))
        out += [f"    derivative(y_stage, robot, p, config, k[{s}], volts)"]
    out += ["    for i in range(n):",
            "        dy = y_new[i] - x[i]",
            "        f[0, i] = dy",
            "        f[1, i] = h * k[0, i] - dy",
            f"        f[2, i] = 2.0 * dy - h * (k[{N_STAGES}, i] + k[0, i])"]
    for r in range(4):
        out += _assignment(f"f[{r + 3}, i]", "0.0", tableau.D[r], range(N_STAGES + 4))
        out[-len(_wrapped(_combination(tableau.D[r], range(N_STAGES + 4)), 12))] = \
            out[-len(_wrapped(_combination(tableau.D[r], range(N_STAGES + 4)), 12))].replace("0.0 + h * (", "h * (")
    out += ["", "",
            "@njit(**JIT_INLINE)",
            "def state_at(x, f, theta, out):",
            '    """The dense output at theta in [0, 1] (scipy\'s Dop853DenseOutput, operation by operation)."""',
            "    rest = 1.0 - theta",
            "    for i in range(x.shape[0]):",
            "        y = f[6, i] * theta",
            "        y = (y + f[5, i]) * rest",
            "        y = (y + f[4, i]) * theta",
            "        y = (y + f[3, i]) * rest",
            "        y = (y + f[2, i]) * theta",
            "        y = (y + f[1, i]) * rest",
            "        y = (y + f[0, i]) * theta",
            "        out[i] = y + x[i]",
            "    return out", "", "",
            "@njit(**JIT_INLINE)",
            "def bernstein(x, f, states, bz):",
            '    """bz[j, i]: the degree-7 Bernstein coefficients on theta in [0, 1] of state_at for the first',
            '    ``states`` states (bz[0] = x, bz[7] = x + f[0]): the polynomial lies in their hull."""',
            "    w = BERNSTEIN_WEIGHTS",
            "    for i in range(states):",
            "        bz[0, i] = x[i]",
            "        for j in range(1, 8):",
            "            total = 0.0",
            "            for r in range(7):",
            "                total += w[j, r] * f[r, i]",
            "            bz[j, i] = x[i] + total"]
    return "\n".join(out) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args()
    text = module_text()
    if args.check:
        if MODULE.read_text() != text:
            print(f"{MODULE} is not what {Path(__file__).name} writes: run it", file=sys.stderr)
            sys.exit(1)
        return
    MODULE.write_text(text)
    print(MODULE)


if __name__ == "__main__":
    main()
