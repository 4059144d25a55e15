"""The tests' oracle: robot geometry, instruments and running errors written once, plainly, from their textbooks and
the 1986 thesis, sharing no code with robocal (nothing here imports ``calib`` or ``acq``).

Why one package: a truth written six times drifts six ways, and a test whose truth restates the production code can
only show that the code agrees with itself.  Every independent generator in ``tests/fakes`` (the thesis Puma, the
URDF chain, the branched tree, the point loads, the Chapter 4 procedures, the backlash sessions) and the benchmarks'
reference chains take their formulas from here:

* :mod:`.chain` -- 4x4 homogeneous rotations and translations, the DH A-matrix as printed in section 3.4 with
  Hayati's ``Rot(y, beta)``, URDF origins (``Rz Ry Rx``), Rodrigues, torques of forces about joint axes, and a
  Jacobian by central differences;
* :mod:`.stations` -- theodolite readings from points by plain trigonometry (section 5.3.1) and eq 4.3.1 back;
* :mod:`.effects` -- the thesis's running errors: transmission error, two-slope joint compliance, cross coupling,
  encoder quantisation, play in a drive;
* :mod:`.beam` -- a cantilever's deflection by integrating ``EI y'' = M`` (not the closed form);
* :mod:`.scheme` -- section 4.3.1's misalignments, compensation into S_fj and the Puma lengths of eq 4.3.15.

Units: mm, rad, N, kg unless a name says otherwise.
"""
