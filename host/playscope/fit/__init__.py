"""Session -> calibration (paper Fig. 4), in the calibration's order: reversals, onset settings,
onsets (the C detector), their refinement, B(q) (bspline, backlash), f_remain, the transition,
the relaxation, the model choice through the fixed-point tables (families, table_build), and the
calibration file (calibration, calibration_check)."""
