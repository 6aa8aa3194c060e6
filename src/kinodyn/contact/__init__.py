"""Avatar-environment contact (Schmidl and Lin): global penetration depth from convex pieces, overlap
removal, CCD IK with joint limits and reach cones, impulses with Coulomb friction.

Modules: :mod:`~kinodyn.contact.setting` (materials, pieces, objects), :mod:`~kinodyn.contact.meshes`
(trimesh, CoACD, cache), :mod:`~kinodyn.contact.scenefile` (YAML scene files),
:mod:`~kinodyn.contact.collide` (sweep and prune, MuJoCo narrow phase), :mod:`~kinodyn.contact.depth`
(equation 1, Algorithm 1), :mod:`~kinodyn.contact.overlap` (priorities), :mod:`~kinodyn.contact.avatar`
(segments, chains, reach cones), :mod:`~kinodyn.contact.resolve` (the avatar loop), :mod:`~kinodyn.contact.impulse`
(equations 6-10), :mod:`~kinodyn.contact.simulate` (figure 3's frame loop), :mod:`~kinodyn.contact.fix`
(cleaning clips), :mod:`~kinodyn.contact.motions` (the scenarios' tracker input),
:mod:`~kinodyn.contact.display` (object shapes along a run, penetrating segments, contact normals: what
the viewer page of ``kinodyn contact run --html`` draws).
Uses the core (skeleton, motion, math.quat, math.array_kernels, kinematics, limits, ik.ccd: the CCD IK of
equations 2-5 with its reach cones), data.library and physics.body.
"""
