"""Figures, one module per kind, all drawn with matplotlib's object API: each function builds a
``matplotlib.figure.Figure`` itself (no pyplot state, no backend switch) and saves it to the path given.
matplotlib is imported inside the functions, so importing optcal stays light."""
