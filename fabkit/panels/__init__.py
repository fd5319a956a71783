"""Multi-panel assemblies (paper §3, §4): panelise, relax, unfold, congruency, merge, feedback."""
