"""The planting mechanisms the core knows, and what the rest of the machine must know of each."""

# plants set per revolution of the driven shaft (five-bar: sun bar; three-arm: carrier)
PLANTS_PER_REVOLUTION = {'five_bar': 1, 'three_arm': 3}
MECHANISMS = tuple(PLANTS_PER_REVOLUTION)

# three-arm pitch-curve interpolants a scene may name; the curves themselves are
# three_arm.pitch_curve.INTERPOLANTS (kept here too so that reading a scene loads no numpy)
PITCH_CURVE_INTERPOLANTS = ('periodic_cubic', 'trigonometric', 'bspline_polar',
                            'bspline_cartesian')
