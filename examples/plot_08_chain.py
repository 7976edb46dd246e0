r"""
Two degrees of freedom: which element is nonlinear, and its law
================================================================

A structure with two masses, each driven by its own white force, measured by two
accelerometers. Its engineer suspects one connection is not linear but not which.
Starting from an all-linear system file, ``hosid diagnose`` tries each candidate effect
in each element, fits the extended system and names the pair whose Wald z passes a
Bonferroni level (:func:`hosid.check.locate.locate`); the named system is then fitted with
emcee, and its modes come with it.
"""

# %%
# The chain and its record
# ------------------------
# A spring and a dashpot from the ground to ``x1``, another pair between ``x1`` and
# ``x2``, whose spring also has a cubic term ``n2[x1-x2]`` that the base file does not
# know. 2000 s of both accelerations at dt = 0.02 s (``hosid simulate --system
# truth.toml --measured acceleration``).
import tomllib

import matplotlib.pyplot as plt
import numpy as np

import hosid
from hosid.check.locate import extended, locate
from hosid.model.system_file import system_from_dict
from hosid.output.locate_report import evidence_figure

LINEAR = """
dofs = ["x1", "x2"]
[[element]]
between = ["ground", "x1"]
terms = ["linear_damping", "linear_stiffness"]
[[element]]
between = ["x1", "x2"]
terms = ["linear_damping", "linear_stiffness"]
[values]
"a1[ground-x1]" = 0.3
"a2[ground-x1]" = 25.0
"a1[x1-x2]" = 0.2
"a2[x1-x2]" = 15.0
"mass[x2]" = 0.8
"S0[x1]" = 2.0
"S0[x2]" = 2.0
"""
linear = system_from_dict(tomllib.loads(LINEAR), "linear chain")
truth = extended(linear, "cubic_stiffness", 1)
values = {**dict(linear.values), "n2[x1-x2]": 0.06}
record = hosid.simulate_chain(truth, truth.vector(values), duration=2000.0, dt=0.02,
                              rng=np.random.default_rng(8), measured="acceleration")  # fmt: skip
print(record)

# %%
# Where is the missing effect?
# ----------------------------
# Four pairs: quadratic damping or cubic stiffness, in either element. Each bar is a
# pair's :math:`|z|`; the dashed line is the level a pair must pass (alpha = 0.05 over
# the four). On the command line: ``hosid diagnose rec.csv --model linear.toml
# --measured acceleration --out diag/``.
found = locate(record, linear)
print(found.decision)
evidence_figure(found)

# %%
# The named system, sampled
# -------------------------
# The system with the named term is fitted as any system is (``hosid fit rec.csv --model
# named.toml``): every element's law with its posterior, the masses and the forces'
# levels. The table shows the posterior against the truth.
tree = hosid.fit(record, found.final, seed=1, progress=False)
post = tree["posterior"]
print(f"{'parameter':>14} {'truth':>8} {'mean':>8} {'sd':>8}")
for name in found.final.param_names:
    draws = post[name].values.ravel()
    print(f"{name:>14} {values[name]:8.4g} {draws.mean():8.4g} {draws.std():8.2g}")

# %%
# The cubic spring, and the modes
# -------------------------------
# The posterior of ``n2[x1-x2]`` against the truth, and the modes of the system
# linearised at the record's response level (``summary.json`` ``modes``; the report's
# Modes table and mode shapes).
from hosid.output.results import attr  # noqa: E402

fig, ax = plt.subplots(figsize=(6, 3))
ax.hist(post["n2[x1-x2]"].values.ravel(), bins=60, color="C0", alpha=0.7)
ax.axvline(values["n2[x1-x2]"], color="k", label="truth")
ax.set_xlabel("n2[x1-x2]")
ax.legend()
for m in attr(tree, "modes") or []:
    f, z = m["frequency_hz"], m["damping_ratio"]
    print(f"mode at {f['mean']:.4f} +- {f['sd']:.1g} Hz, damping ratio {z['mean']:.4f} "
          f"+- {z['sd']:.1g}, shape {np.round(m['shape'], 3)}")  # fmt: skip
