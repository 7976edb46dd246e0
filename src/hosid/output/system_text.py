r"""A system's equations of motion as text, from a fit's ``system`` attribute.

Element :math:`e` between :math:`i` and :math:`j` pushes :math:`j` by :math:`-f_e(r_e,
\dot r_e)` and :math:`i` by :math:`+f_e` (:mod:`hosid.model.system`): dof :math:`d`
reads ``m_d ẍ_d + sum_e B_ed f_e = F_d``, each element's force written with its terms'
coefficients named by the element (``a1[x1-x2] ṙ``).
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["system_model"]

#: A drift term's force on the relative motion r = q_j - q_i.
TERM_TEXT = {
    "linear_damping": ("a1", "ṙ"),
    "quadratic_damping": ("n1", "ṙ|ṙ|"),
    "coulomb_friction": ("mu", "sign(ṙ)"),
    "linear_stiffness": ("a2", "r"),
    "quadratic_stiffness": ("b2", "r²"),
    "cubic_stiffness": ("n2", "r³"),
    "excitation_mean": ("m", "(-1)"),
}


def _force(element: Mapping) -> str:
    label = "-".join(element["between"])
    parts = []
    for name in element["terms"]:
        p, feature = TERM_TEXT.get(name, (name, ""))
        parts.append(f"{p}[{label}] {feature}".strip())
    j = element["between"][1]
    r = f"{j} - {element['between'][0]}" if element["between"][0] != "ground" else j
    return "(" + " + ".join(parts) + f")(r = {r})"


def system_model(system: Mapping) -> dict:
    """``equation`` (one line a dof, joined by ``; ``) and ``terms`` (rows of name, kind,
    parameters) of a fit's ``system`` attribute (:meth:`hosid.model.system.System.describe`).
    """
    lines = []
    masses = system.get("masses") or {}
    driven = set(system.get("driven") or [])
    for d in system["dofs"]:
        m = masses.get(d)
        lhs = ("" if m == 1.0 else (f"{m:g} " if m is not None else f"mass[{d}] ")) + f"ẍ_{d}"
        for el in system["elements"]:
            a, b = el["between"]
            if d in (a, b):
                lhs += (" + " if d == b else " - ") + _force(el)
        lines.append(f"{lhs} = " + (f"F_{d}" if d in driven else "0"))
    terms = [
        (f"{name} [{'-'.join(el['between'])}]", "drift",
         f"{TERM_TEXT.get(name, (name,))[0]}[{'-'.join(el['between'])}]")
        for el in system["elements"] for name in el["terms"]
    ]  # fmt: skip
    terms += [("mass", "inertia", f"mass[{d}]") for d in system["dofs"] if masses.get(d) is None]
    terms += [("excitation_level", "excitation", f"S0[{d}]") for d in sorted(driven)]
    return {"equation": "; ".join(lines), "terms": terms}
