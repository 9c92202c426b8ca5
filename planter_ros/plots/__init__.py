"""Figures for people (matplotlib, Agg backend); imported only when a plot is asked for."""
