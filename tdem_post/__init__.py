"""tdem post-processing: profiles, analytical solutions, fits, ETC, plots."""
