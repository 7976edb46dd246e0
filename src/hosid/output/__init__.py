"""Output: the fit's DataTree and summary, plots, the HTML report."""
