r"""``[[contact]]`` in case files: the block pressed on a rigid plane, run through ``hyperfem run``'s build.

``cases/block_on_plane.toml``: a unit cube (``meshes/block_h0.34.msh``) of
Neo-Hookean rubber (E = 1 MPa, :math:`\nu` = 0.3) on the frictionless plane
:math:`z = -\hat d/2`, rollers on :math:`x = 0`, :math:`y = 0`, the top pushed
down by 0.2 m. The exact state is uniaxial compression with free lateral
faces (the closed form of ``tests/test_contact.py``): the force on the plane is
:math:`|P_{zz}(\lambda)|` times 1 m², :math:`\lambda` the current height.
Serially and under ``mpiexec -n 2``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

pytest.importorskip("ipctk")

from hyperfem.app import build, check_groups, load_case, script  # noqa: E402
from hyperfem.app.build import build_domain, check_dimensions  # noqa: E402
from hyperfem.app.calls import source  # noqa: E402
from hyperfem.app.casefile import CaseFileError  # noqa: E402
from hyperfem.contact import PlaneBarrier, PlaneContact, SphereBarrier  # noqa: E402

from case_texts import ROOT  # noqa: E402

CASE = ROOT / "cases" / "block_on_plane.toml"
SPHERE = {"type": "sphere", "center": [0.5, 0.5, -2.0005], "radius": 2.0, "dhat": 1e-3}
CYLINDER = {"type": "cylinder", "point": [0.5, 0.0, -2.0005], "axis": [0.0, 1.0, 0.0], "radius": 2.0, "dhat": 1e-3}
E, NU = 1.0e6, 0.3


def uniaxial_stress(stretch: float) -> float:
    r""":math:`P_{zz}` of compressible Neo-Hookean uniaxial stress (lateral faces free) at ``stretch``."""
    mu, lam = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    lt = 1.0
    for _ in range(60):  # P_xx(lt) = mu lt + (lam ln J - mu) / lt = 0
        J = stretch * lt * lt
        g = mu * lt + (lam * np.log(J) - mu) / lt
        dg = mu + 2.0 * lam / lt**2 - (lam * np.log(J) - mu) / lt**2
        lt -= g / dg
    J = stretch * lt * lt
    return mu * stretch + (lam * np.log(J) - mu) / stretch


def test_contact_case_builds_the_plane_contact_and_passes_it_to_the_solver():
    """The plan binds PlaneContact to the problem, gives it to NewtonSolver and records it; the script shows it."""
    case = load_case(CASE)
    (contact,) = case.contacts
    assert (contact.type, contact.boundary, contact.point, contact.dhat) == ("plane", "bottom", (0.0, 0.0, -5e-4), 1e-3)
    text = script(case)
    assert "contact = PlaneContact('bottom', point=(0.0, 0.0, -0.0005), normal=(0.0, 0.0, 1.0), dhat=0.001)" \
           ".bind(problem)" in text
    assert "external_energies=[contact]" in text and "Recorder(contact),  # contact[0]" in text
    compile(text, "block_on_plane.py", "exec")
    check_groups(case, build_domain(case, MPI.COMM_WORLD))


def test_block_on_plane_matches_the_closed_form_and_the_reaction(shared_tmp):
    """Contact force = |P_zz(height)| to 0.1 % and = -(reaction on the top face) at every step; no penetration."""
    built = build(load_case(CASE, ["output.fields=[]", "output.checkpoint=false"], output=shared_tmp / "out"))
    barrier = built.variables["contact"]
    assert isinstance(barrier, PlaneBarrier)
    summary = built.simulation.run()
    assert summary["completed"] and summary["steps"] >= 2
    for row in summary["rows"][1:]:
        assert row["contact_min_distance"] > 0.0 and row["contact_active"] > 0
        assert row["contact_force"][2] == pytest.approx(-row["reaction_top_Fz"], rel=1e-9)
    u = built.problem.u.x.array
    comm = built.domain.comm
    z = barrier.nodes.positions(u)[:, 2]
    height = 0.8 - comm.allreduce(float(z.sum()), op=MPI.SUM) / barrier.nodes.total
    force = summary["rows"][-1]["contact_force"][2]
    assert force == pytest.approx(-uniaxial_stress(height), rel=1e-3)
    assert force == pytest.approx(2.393e5, rel=2e-3)  # this mesh and d-hat: 239329 N (serial and 2 ranks)
    # The summary's contact entry (one per [[contact]], like reactions): the last force, its moment about the origin
    # (the centre of the pressure at the middle of the laterally expanded bottom, x = y = width / 2), pairs, gap.
    entry = summary["contact"]["contact"]
    assert entry["type"] == "PlaneContact" and entry["boundaries"] == ["bottom"]
    assert entry["force"] == summary["rows"][-1]["contact_force"] and entry["active"] > 0
    x = barrier.nodes.positions(u)[:, 0]
    width = comm.allreduce(float(x.max()) if len(x) else 0.0, op=MPI.MAX)
    assert entry["moment"] == pytest.approx([force * width / 2, -force * width / 2, 0.0], rel=1e-3, abs=1e-6 * force)


@pytest.mark.parametrize(
    "change, expected",
    [
        ({"friction": -0.3}, "contact[0].friction: must be >= 0"),
        ({"friction_epsilon": 0.0}, "contact[0].friction_epsilon: must be > 0"),
        ({"normal": [0.0, 0.0, 0.0]}, "contact[0].normal: must not be zero"),
        ({"dhat": -1.0}, "contact[0].dhat: must be > 0, got -1.0"),
        ({"motion": [0.0, 1.0]}, "contact[0].motion: 2 components for a point of 3"),
        ({"type": "cone"}, "contact[0].type: unknown value 'cone'"),
        (CYLINDER | {"axis": [0.0, 0.0, 0.0]}, "contact[0].axis: must not be zero"),
        ({"type": "cylinder", "point": [0.5, 0.0, -2.0005], "radius": 1.0}, "contact[0]: missing required key 'axis'"),
        (CYLINDER | {"point": [0.5, 0.0]}, "contact[0].point: expected 3 numbers, got 2"),
        ({"gap": 1.0}, "contact[0].gap: unknown key"),
        ({"type": "sphere"}, "contact[0].point: unknown key"),
        (SPHERE | {"radius": 0.0}, "contact[0].radius: must be > 0"),
        (SPHERE | {"center": [0.5, 0.5]}, "contact[0].center: 2 components"),
        (SPHERE | {"motion": [0.0, 1.0]}, "contact[0].motion: 2 components for a center of 3"),
        (SPHERE | {"motion": [0.0, 0.0, 1.0], "path": {"times": [0.0, 1.0], "points": [[0, 0, 0], [0, 0, 1]]}},
         "contact[0].path: give either path or motion, not both"),
        (SPHERE | {"path": {"times": [0.0, 1.0], "points": [[0.0, 0.0], [0.0, 0.1]]}},
         "contact[0].path.points: rows of 2 components for a center of 3"),
        ({"path": {"times": [0.0, 1.0]}}, "contact[0].path: missing required key 'points'"),
    ],
)
def test_bad_contact_entries_name_their_key(shared_tmp, change, expected):
    import tomllib

    from hyperfem.app.casefile import check_case

    data = tomllib.loads(CASE.read_text())
    data["mesh"]["file"] = str(ROOT / "meshes" / "block_h0.34.msh")
    if change.get("type") in ("sphere", "cylinder") and "radius" in change:
        data["contact"][0] = {"boundary": "bottom"}
    data["contact"][0].update(change)
    with pytest.raises(CaseFileError) as info:
        case = check_case(data, shared_tmp / "bad.toml")
        check_dimensions(case, build_domain(case, MPI.COMM_WORLD))
    assert expected in str(info.value)


def _sphere_case(shared_tmp):
    """The block's bottom above a rigid sphere of radius 2 (instead of the plane), its top pushed down by 2 cm."""
    import tomllib

    from hyperfem.app.casefile import check_case

    data = tomllib.loads(CASE.read_text())
    data["mesh"]["file"] = str(ROOT / "meshes" / "block_h0.34.msh")
    data["contact"][0] = {"boundary": "bottom", **SPHERE}
    data["bc"][2]["value"] = [-0.02]
    data["output"].update({"fields": [], "checkpoint": False, "directory": str(shared_tmp / "sphere")})
    return check_case(data, shared_tmp / "sphere.toml")


def test_sphere_contact_in_a_case_file(shared_tmp):
    """``type = "sphere"``: the plan binds SphereContact (the script shows it); the block pressed on the sphere:
    a force, never penetrating, and the sphere's force balances the reaction of the pushed face at every step."""
    case = _sphere_case(shared_tmp)
    text = script(case)
    assert "contact = SphereContact('bottom', center=(0.5, 0.5, -2.0005), radius=2.0, dhat=0.001).bind(problem)" in text
    built = build(case)
    assert isinstance(built.variables["contact"], SphereBarrier)
    summary = built.simulation.run()
    rows = summary["rows"]
    assert summary["completed"] and rows[-1]["contact_active"] > 0 and rows[-1]["contact_force"][2] > 1e3
    for row in rows[1:]:  # (the nodes nearest the top of the sphere reach it after the first step)
        assert row["contact_min_distance"] > 0.0
        assert row["contact_force"][2] == pytest.approx(-row["reaction_top_Fz"], rel=1e-8, abs=1e-6)


PLANE = {"type": "plane", "point": [0.0, 0.0, -5e-4], "normal": [0.0, 0.0, 1.0], "dhat": 1e-3}


@pytest.mark.parametrize("obstacle", ["sphere", "plane", "cylinder"])
def test_obstacle_path_in_a_case_file_equals_its_motion(shared_tmp, obstacle):
    """``path = {times, points}`` on a sphere, plane or cylinder (as on a tool): the script prints
    ``motion=Waypoints(...)`` and compiles; the obstacle pushed 2 cm up into the resting block along the path gives
    the forces of ``motion`` to round-off, balanced by the reaction of the held top."""
    import tomllib

    from hyperfem.app.casefile import check_case

    runs = []
    shape = {"sphere": SPHERE, "plane": PLANE, "cylinder": CYLINDER}[obstacle]
    for i, keys in enumerate(({"path": {"times": [0.0, 1.0], "points": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.02]]}},
                              {"motion": [0.0, 0.0, 0.02]})):
        data = tomllib.loads(CASE.read_text())
        data["mesh"]["file"] = str(ROOT / "meshes" / "block_h0.34.msh")
        data["contact"][0] = {"boundary": "bottom", **shape, **keys}
        data["bc"][2]["value"] = [0.0]
        folder = shared_tmp / f"{obstacle}_path{i}"
        data["output"].update({"fields": [], "checkpoint": False, "directory": str(folder)})
        case = check_case(data, shared_tmp / f"{obstacle}_path{i}.toml")
        text = script(case)
        compile(text, f"{obstacle}_path.py", "exec")
        if i == 0:
            assert "motion=Waypoints(times=(0.0, 1.0), points=((0.0, 0.0, 0.0), (0.0, 0.0, 0.02)))" in " ".join(
                text.split())
        summary = build(case).simulation.run()
        assert summary["completed"]
        runs.append(summary["rows"])
    assert runs[0][-1]["contact_force"][2] > 1e3
    for a, b in zip(runs[0][1:], runs[1][1:], strict=True):
        assert a["contact_force"] == pytest.approx(b["contact_force"], rel=1e-10, abs=1e-8)
        assert a["contact_force"][2] == pytest.approx(-a["reaction_top_Fz"], rel=1e-8, abs=1e-6)


def test_cylinder_contact_in_a_case_file(shared_tmp):
    """``type = "cylinder"``: CylinderContact in the script; the block pressed 2 cm on a roller along y: the force
    balances the reaction at every step, none along the axis, never penetrating."""
    import tomllib

    from hyperfem.app.casefile import check_case
    from hyperfem.contact import CylinderBarrier

    data = tomllib.loads(CASE.read_text())
    data["mesh"]["file"] = str(ROOT / "meshes" / "block_h0.34.msh")
    data["contact"][0] = {"boundary": "bottom", **CYLINDER}
    data["bc"][2]["value"] = [-0.02]
    data["output"].update({"fields": [], "checkpoint": False, "directory": str(shared_tmp / "cylinder")})
    case = check_case(data, shared_tmp / "cylinder.toml")
    text = script(case)
    assert ("contact = CylinderContact('bottom', point=(0.5, 0.0, -2.0005), axis=(0.0, 1.0, 0.0), radius=2.0, "
            "dhat=0.001).bind(") in text
    built = build(case)
    assert isinstance(built.variables["contact"], CylinderBarrier)
    summary = built.simulation.run()
    rows = summary["rows"]
    assert summary["completed"] and rows[-1]["contact_active"] > 0
    for row in rows[1:]:
        assert row["contact_min_distance"] > 0.0 and abs(row["contact_force"][1]) < 1e-9 * row["contact_force"][2]
        assert row["contact_force"][2] == pytest.approx(-row["reaction_top_Fz"], rel=1e-8, abs=1e-6)


def test_contact_in_a_dynamic_run(shared_tmp):
    """The block pressed on the plane in a dynamic (Newmark) run: four steps of 0.05 s, no cutback, never penetrating.

    The integrator's guess :math:`u_n + \\Delta t\\,v_n` of the third step goes through the plane; the solver pulls it
    back along the collision filter (it used to assemble the barrier there: NaN, a failed factorization).
    """
    changes = ["material[0].density=1000.0", 'stepping={type = "dynamic", dt = 0.05, t_end = 0.2}']
    case = load_case(CASE, [*changes, "output.fields=[]", "output.checkpoint=false"], output=shared_tmp / "dyn")
    text = script(case)
    assert "problem = dyn.IncrementalProblem(base, dyn.Newmark()" in text and "external_energies=[contact]" in text
    summary = build(case).simulation.run()
    rows = summary["rows"]
    assert summary["completed"] and summary["steps"] == 4 and summary["rejected"] == 0
    assert all(0.0 < row["contact_min_distance"] < 1e-3 and row["contact_force"][2] > 0.0 for row in rows[1:])
    assert all(np.isfinite(row["kinetic_energy"]) for row in rows)


def test_moving_obstacle_with_generalized_alpha_runs(shared_tmp):
    """A moving plane with scheme = "generalized_alpha" (refused before): the obstacle is placed at the end of each
    step (tests/test_contact_dynamics.py), four steps without cutback, the bottom off the plane at every step."""
    over = ["material[0].density=1000.0", "contact[0].motion=[0.0, 0.0, 0.01]", "output.fields=[]",
            "output.checkpoint=false",
            'stepping={type = "dynamic", scheme = "generalized_alpha", dt = 0.05, t_end = 0.2}']
    case = load_case(CASE, over, output=shared_tmp / "alpha")
    assert "dyn.GeneralizedAlpha()" in script(case)
    built = build(case)
    summary = built.simulation.run()
    rows = summary["rows"]
    assert summary["completed"] and summary["steps"] == 4 and summary["rejected"] == 0
    assert built.variables["contact"].time == pytest.approx(0.2, rel=1e-12)
    assert all(0.0 < row["contact_min_distance"] < 1e-3 and row["contact_force"][2] > 0.0 for row in rows[1:])


def test_unknown_contact_boundary_lists_the_groups():
    case = load_case(CASE, ["contact[0].boundary=botom"])
    with pytest.raises(CaseFileError) as info:
        check_groups(case, build_domain(case, MPI.COMM_WORLD))
    message = str(info.value)
    assert "contact[0].boundary: no boundary 'botom'" in message and "(did you mean 'bottom'?)" in message
    assert "bottom, sides, top, x0, y0" in message


def test_plan_node_of_the_contact_is_the_library_class():
    """Go to definition: the plan calls PlaneContact itself, and its bind method on the problem."""
    from hyperfem.app.plan import plan

    (statement,) = [s for s in plan(load_case(CASE)) if s.target == "contact"]
    call = statement.value
    assert call.function.value.function is PlaneContact and call.function.name == "bind"
    assert source(call.args[0]) == "problem"
    assert dataclasses.is_dataclass(PlaneContact)
    assert Path(CASE).exists()


TILTED = """name = "tilted"
[mesh]
file = "{mesh}"
[[material]]
law = "neo_hookean"
E = 1.0e6
nu = 0.3
[[bc]]
type = "clamp"
boundary = "clamped"
[[bc]]
type = "displacement"          # a roller: the contact force's y part goes into this support
boundary = "free_end"
value = [0.0]
components = ["y"]
[[contact]]
type = "plane"
boundary = "free_end"
point = [5.02, 2.05, 0.0]
normal = [-0.8, -0.6, 0.0]
dhat = 0.05
motion = [-0.2, 0.0, 0.0]
[stepping]
increment = 0.5
[output]
fields = []
checkpoint = false
progress = false
"""


def test_reactions_balance_the_contact_force_where_contact_nodes_are_held(shared_tmp):
    """A tilted plane pushes a face whose y component is held: the supports take the contact force, all of it.

    The barrier's gradient at held dofs is left out of the Newton residual (those rows are the
    Dirichlet conditions) but acts on the supports: before the fix the y balance was off by 1.1e5 N.
    """
    path = shared_tmp / "tilted.toml"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text(TILTED.format(mesh=ROOT / "meshes" / "beam_h2.msh"))
    MPI.COMM_WORLD.Barrier()
    summary = build(load_case(path, output=shared_tmp / "tilted")).simulation.run()
    row = summary["rows"][-1]
    force = np.asarray(row["contact_force"])
    total = np.array([row["reaction_total_Fx"], row["reaction_total_Fy"], row["reaction_total_Fz"]])
    assert abs(force[1]) > 1e4  # the held component carries a real part of the contact force
    np.testing.assert_allclose(total, -force, rtol=1e-8, atol=1e-6 * np.abs(force).max())


def test_friction_key_reaches_the_contact(shared_tmp):
    """``friction`` and ``friction_epsilon`` in [[contact]] go to PlaneContact (the script shows them)."""
    import tomllib

    from hyperfem.app.casefile import check_case

    data = tomllib.loads(CASE.read_text())
    data["mesh"]["file"] = str(ROOT / "meshes" / "block_h0.34.msh")
    data["contact"][0].update({"friction": 0.3, "friction_epsilon": 1e-4})
    case = check_case(data, shared_tmp / "rough.toml")
    (contact,) = case.contacts
    assert (contact.friction, contact.friction_epsilon) == (0.3, 1e-4)
    text = script(case)
    assert "friction=0.3," in text and "friction_epsilon=0.0001" in text
    compile(text, "rough.py", "exec")


# -- mesh contact: two bodies (type = "pair"), self-contact ("self"), a rigid triangulated tool ("tool") -------------

PAIR = """name = "two_blocks"
[mesh]
file = "blocks.msh"                  # lower below z = 0, upper above z = 5e-4 (non-matching facets)
[[material]]
law = "neo_hookean"
E = 1.0
nu = 0.3
[[bc]]
type = "displacement"
boundary = "x0"
value = [0.0]
components = ["x"]
[[bc]]
type = "displacement"
boundary = "y0"
value = [0.0]
components = ["y"]
[[bc]]
type = "displacement"
boundary = "lower_bottom"
value = [0.0]
components = ["z"]
[[bc]]
type = "displacement"
boundary = "upper_top"
value = [-0.2]
components = ["z"]
[[contact]]
type = "pair"
boundaries = ["lower_top", "upper_bottom"]
dhat = 1e-3
[stepping]
increment = 0.25
max_increment = 0.25
[solver]
rtol = 1e-10
atol = 1e-12
[output]
reactions = ["upper_top"]
fields = []
checkpoint = false
progress = false
"""

TOOL = """name = "block_on_tool"
[mesh]
file = "{mesh}"
[[material]]
law = "neo_hookean"
E = 1.0
nu = 0.3
[[bc]]
type = "displacement"
boundary = "x0"
value = [0.0]
components = ["x"]
[[bc]]
type = "displacement"
boundary = "y0"
value = [0.0]
components = ["y"]
[[bc]]
type = "displacement"
boundary = "top"
value = [-0.2]
components = ["z"]
[[contact]]
type = "tool"
boundaries = ["bottom"]
file = "plate.stl"                   # relative to this file
dhat = 1e-3
[stepping]
increment = 0.25
max_increment = 0.25
[solver]
rtol = 1e-10
atol = 1e-12
[output]
reactions = ["top"]
fields = []
checkpoint = false
progress = false
"""


def _write_pair(folder: Path, text: str = PAIR) -> Path:
    """The two stacked blocks (hf.mesh.write_stacked_blocks_mesh) and the pair case beside them (rank 0, then all)."""
    from hyperfem.mesh import write_stacked_blocks_mesh

    path = folder / "two_blocks.toml"
    if MPI.COMM_WORLD.rank == 0:
        if not (folder / "blocks.msh").exists():
            write_stacked_blocks_mesh(folder / "blocks.msh", 0.5, 0.34, 5e-4)
        path.write_text(text)
    MPI.COMM_WORLD.Barrier()
    return path


def _write_tool(folder: Path, text: str = TOOL) -> Path:
    """A two-triangle plate at z = -d-hat/2 (binary STL, meshio) and the block pressed onto it (rank 0, then all)."""
    import meshio

    path = folder / "block_on_tool.toml"
    if MPI.COMM_WORLD.rank == 0:
        plate = [[-1.0, -1.0, -5e-4], [3.0, -1.0, -5e-4], [3.0, 3.0, -5e-4], [-1.0, 3.0, -5e-4]]
        meshio.write_points_cells(folder / "plate.stl", plate, [("triangle", np.array([[0, 1, 2], [0, 2, 3]]))],
                                  binary=True)
        path.write_text(text.format(mesh=ROOT / "meshes" / "block_h0.34.msh"))
    MPI.COMM_WORLD.Barrier()
    return path


def test_pair_contact_case_transmits_the_force_between_two_blocks(shared_tmp):
    """``type = "pair"``: SurfaceContact of lower_top and upper_bottom; the force on lower_top = the top reaction
    (1e-8) at every step, about -0.10866 N at the end (as tests/test_contact_surfaces.py through the API)."""
    from hyperfem.contact import MeshBarrier, SurfaceContact

    case = load_case(_write_pair(shared_tmp), output=shared_tmp / "pair")
    (contact,) = case.contacts
    assert (contact.type, contact.boundaries, contact.dhat, contact.boundary) == (
        "pair", ("lower_top", "upper_bottom"), 1e-3, None)
    text = script(case)
    assert "contact = SurfaceContact(['lower_top', 'upper_bottom'], dhat=0.001).bind(problem)" in text
    assert "external_energies=[contact]" in text and "Recorder(contact),  # contact[0]" in text
    compile(text, "two_blocks.py", "exec")
    built = build(case)
    barrier = built.variables["contact"]
    assert isinstance(barrier, MeshBarrier) and isinstance(barrier.contact, SurfaceContact)
    summary = built.simulation.run()
    rows = summary["rows"]
    assert summary["completed"] and summary["steps"] == 4
    for row in rows[1:]:
        assert row["contact_force"][2] == pytest.approx(row["reaction_upper_top_Fz"], rel=1e-8)
    assert 0.0 < rows[-1]["contact_min_distance"] < 1e-3
    assert rows[-1]["contact_force"][2] == pytest.approx(-0.10866, rel=1e-3)


def test_self_contact_case_runs_and_equals_the_pair(shared_tmp):
    """``type = "self"`` over both faces of the gap (one surface whose pairs may be any two of its primitives): the
    case runs end to end and gives the pair's force (the blocks' own faces are flat, so no other pair is active)
    to 1e-8, balanced by the reaction at every step."""
    folder = shared_tmp / "self"
    if MPI.COMM_WORLD.rank == 0:
        folder.mkdir(exist_ok=True)
    MPI.COMM_WORLD.Barrier()
    runs = {}
    for kind in ("pair", "self"):
        case = load_case(_write_pair(folder, PAIR.replace('type = "pair"', f'type = "{kind}"')),
                         output=folder / kind)
        assert case.contacts[0].type == kind
        compile(script(case), f"{kind}.py", "exec")
        summary = build(case).simulation.run()
        assert summary["completed"]
        runs[kind] = summary["rows"]
    for pair, self_ in zip(runs["pair"][1:], runs["self"][1:], strict=True):
        assert self_["contact_min_distance"] > 0.0
        assert self_["contact_force"][2] == pytest.approx(self_["reaction_upper_top_Fz"], rel=1e-8)
        assert self_["contact_force"] == pytest.approx(pair["contact_force"], rel=1e-8, abs=1e-12)


def test_tool_contact_case_presses_the_block_on_an_stl_plate(shared_tmp):
    """``type = "tool"``: ToolContact of a binary STL plate (file relative to the case file); the tool's force on
    the block = -(reaction at the top) to 1e-8 at every step; the script reads the file beside the case."""
    from hyperfem.contact import MeshBarrier, ToolContact

    case = load_case(_write_tool(shared_tmp), output=shared_tmp / "tool")
    (contact,) = case.contacts
    assert contact.file == (shared_tmp / "plate.stl").resolve() and contact.boundaries == ("bottom",)
    text = script(case)
    assert "contact = ToolContact(['bottom'], file=case_dir / 'plate.stl', dhat=0.001, name='contact')" \
           ".bind(problem)" in text
    compile(text, "block_on_tool.py", "exec")
    built = build(case)
    barrier = built.variables["contact"]
    assert isinstance(barrier, MeshBarrier) and isinstance(barrier.contact, ToolContact)
    summary = built.simulation.run()
    rows = summary["rows"]
    assert summary["completed"] and rows[-1]["contact_force"][2] > 0.1
    supports = [name.removesuffix("_Fz").removeprefix("reaction_") for name in rows[-1] if name.endswith("_Fz")]
    for row in rows[1:]:
        assert row["contact_min_distance"] > 0.0
        assert row["contact_force"][2] == pytest.approx(-row["reaction_top_Fz"], rel=1e-8)
        if "total" in supports:  # the tool's moment about the origin balances the supports'
            total = np.array([row[f"reaction_total_M{c}"] for c in "xyz"])
            assert row["contact_moment"] == pytest.approx(-total, rel=1e-8, abs=1e-10 * np.abs(total).max())
    assert "total" in supports and np.abs(rows[-1]["contact_moment"]).max() > 0.01
    if MPI.COMM_WORLD.rank == 0:  # the CSV (rank 0 writes it) has the contact's columns, lists spread
        import csv

        (path,) = (shared_tmp / "tool").glob("*.csv")
        table = list(csv.DictReader(path.open()))
        assert len(table) == len(rows)
        for column in ("contact_force_2", "contact_moment_0", "contact_moment_2", "contact_active",
                       "contact_min_distance"):
            assert column in table[-1]
        assert float(table[-1]["contact_force_2"]) == pytest.approx(rows[-1]["contact_force"][2], rel=1e-12)
        assert float(table[-1]["contact_moment_1"]) == pytest.approx(rows[-1]["contact_moment"][1], rel=1e-12)


def test_surface_contact_keys_reach_the_script(shared_tmp):
    """self, pair and tool keys (safety, name, subdivision, motion, profile, offset, scale) become API keywords."""
    self_contact = ('[[contact]]\ntype = "self"\nboundaries = ["upper_top"]\nsafety = 0.5\nname = "folds"\n'
                    'subdivision = 3\n')
    tool = ('[[contact]]\ntype = "tool"\nboundaries = ["upper_top"]\nfile = "plate.stl"\nmotion = [0.0, 0.0, 0.1]\n'
            'profile = "steady"\noffset = [0.0, 0.0, 2.0]\nscale = 0.5\nstiffness = 10.0\n')
    path = _write_pair(shared_tmp, PAIR.replace("[stepping]", self_contact + tool + "[stepping]"))
    _write_tool(shared_tmp)
    case = load_case(path)
    assert [c.type for c in case.contacts] == ["pair", "self", "tool"]
    text = script(case)
    flat = " ".join(text.split()).replace("( ", "(").replace(", )", ")")  # the call on one line
    assert "contact_0 = SurfaceContact(['lower_top', 'upper_bottom'], dhat=0.001, name='contact_0')" in flat
    assert "contact_1 = SurfaceContact(['upper_top'], safety=0.5, subdivision=3, name='folds').bind(problem)" in flat
    assert ("contact_2 = ToolContact(['upper_top'], file=case_dir / 'plate.stl', motion=(0.0, 0.0, 0.1), "
            "profile=Steady(1.0), offset=(0.0, 0.0, 2.0), scale=0.5, stiffness=10.0, name='contact_2')") in flat
    assert "external_energies=[contact_0, contact_1, contact_2]" in text
    assert "from hyperfem.contact import SurfaceContact, ToolContact" in text
    compile(text, "surfaces.py", "exec")
    check_groups(case, build_domain(case, MPI.COMM_WORLD))


@pytest.mark.parametrize(
    "change, expected",
    [
        ('boundaries = ["lower_top", "upper_bottom", "sides"]',
         "contact[0].boundaries: a pair names exactly two facet groups, got 3"),
        ('boundaries = ["lower_top", "lower_top"]', "contact[0].boundaries: 'lower_top' is named twice"),
        ('boundary = "lower_top"', "contact[0].boundary: unknown key (did you mean 'boundaries'?); keys of a contact "
                                   "of type 'pair': type, boundaries, dhat, stiffness, safety, name"),
        ('friction = -0.3', "contact[0].friction: must be >= 0"),
        ('safety = 1.0', "contact[0].safety: must be < 1, got 1.0"),
        ('name = "a b"', "contact[0].name: use letters, digits and _.+- only"),
        ('subdivision = 0', "contact[0].subdivision: must be >= 1, got 0"),
        ('subdivision = 9', "contact[0].subdivision: must be <= 8, got 9"),
    ],
)
def test_bad_pair_entries_are_one_line(shared_tmp, change, expected):
    text = PAIR.replace('boundaries = ["lower_top", "upper_bottom"]\n', change + "\n", 1)
    if change.startswith(("friction", "safety", "name", "subdivision")):
        text = PAIR.replace("dhat = 1e-3\n", f"dhat = 1e-3\n{change}\n", 1)
    with pytest.raises(CaseFileError) as info:
        load_case(_write_pair(shared_tmp, text))
    message = str(info.value)
    assert expected in message and "\n" not in message


@pytest.mark.parametrize(
    "old, new, expected",
    [
        ('file = "plate.stl"', 'file = "missing.stl"', "contact[0].file: tool surface file not found: "),
        ('dhat = 1e-3', 'dhat = 1e-3\nfriction_epsilon = 0.0', "contact[0].friction_epsilon: must be > 0"),
        ('dhat = 1e-3', 'dhat = 1e-3\nscale = 0.0', "contact[0].scale: must be > 0"),
        ('boundaries = ["bottom"]', 'boundaries = []', "contact[0].boundaries: name at least one facet group"),
    ],
)
def test_bad_tool_entries_are_one_line(shared_tmp, old, new, expected):
    with pytest.raises(CaseFileError) as info:
        load_case(_write_tool(shared_tmp, TOOL.replace(old, new, 1)))
    message = str(info.value)
    assert expected in message and "\n" not in message


@pytest.mark.parametrize(
    "change, expected",
    [
        ("motion = [0.0, 1.0]", "contact[0].motion: 2 components (the mesh"),
        ("offset = [0.0, 1.0]", "contact[0].offset: 2 components (the mesh"),
        ("path = {times = [0.0, 1.0], points = [[0.0, 0.0], [0.0, 0.1]]}",
         "contact[0].path.points: rows of 2 components (the mesh"),
    ],
)
def test_tool_vectors_of_the_wrong_dimension_are_one_line(shared_tmp, change, expected):
    """A tool's motion, offset and path take one entry per coordinate of the mesh (2 on a 2D mesh): checked with the
    mesh, as a plane's point."""
    case = load_case(_write_tool(shared_tmp, TOOL.replace("dhat = 1e-3", f"dhat = 1e-3\n{_braces(change)}", 1)))
    with pytest.raises(CaseFileError) as info:
        check_dimensions(case, build_domain(case, MPI.COMM_WORLD))
    message = str(info.value)
    assert expected in message and "has 3 displacement components" in message and "\n" not in message


def test_unknown_surface_contact_group_lists_the_groups(shared_tmp):
    case = load_case(_write_pair(shared_tmp, PAIR.replace('"upper_bottom"]', '"upper_botom"]')))
    with pytest.raises(CaseFileError) as info:
        check_groups(case, build_domain(case, MPI.COMM_WORLD))
    message = str(info.value)
    assert "contact[0].boundaries[1]: no boundary 'upper_botom'" in message
    assert "(did you mean 'upper_bottom'?)" in message and "\n" not in message


def test_duplicate_contact_output_names_are_refused(shared_tmp):
    second = '[[contact]]\ntype = "self"\nboundaries = ["upper_top"]\nname = "contact_0"\n'
    with pytest.raises(CaseFileError) as info:
        load_case(_write_pair(shared_tmp, PAIR.replace("[stepping]", second + "[stepping]")))
    assert "contact[1].name: 'contact_0' is the output name of contact[0] too" in str(info.value)


def test_cli_refuses_a_pair_with_three_boundaries_in_one_line(shared_tmp, capsys):
    """``hyperfem check`` prints the one-line message and exits non-zero."""
    from hyperfem.app.main import main

    text = PAIR.replace('["lower_top", "upper_bottom"]', '["lower_top", "upper_bottom", "sides"]')
    path = _write_pair(shared_tmp, text)
    with pytest.raises(SystemExit) as info:
        main(["check", str(path)])
    assert info.value.code != 0
    if MPI.COMM_WORLD.rank == 0:
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("hyperfem: error: ")
        assert "contact[0].boundaries: a pair names exactly two facet groups, got 3" in lines[0]


def test_tie_case_glues_two_blocks_in_tension(shared_tmp):
    """``type = "tie"``: the two blocks glued (TieContact) and pulled apart by 0.2: the tie's force on upper_bottom
    = minus the top reaction, the uniaxial closed form P_zz(1.1) = 0.0930774 (tests/test_contact_tie.py)."""
    from hyperfem.contact import TieBarrier

    text = PAIR.replace('type = "pair"\nboundaries = ["lower_top", "upper_bottom"]\ndhat = 1e-3',
                        'type = "tie"\nboundaries = ["upper_bottom", "lower_top"]')
    text = text.replace("value = [-0.2]", "value = [0.2]")
    text = text.replace("rtol = 1e-10\natol = 1e-12", "rtol = 1e-10\natol = 1e-7")  # the penalty's round-off floor
    folder = shared_tmp / "tie"
    if MPI.COMM_WORLD.rank == 0:
        folder.mkdir(exist_ok=True)
    MPI.COMM_WORLD.Barrier()
    case = load_case(_write_pair(folder, text), output=folder / "out")
    (contact,) = case.contacts
    assert (contact.type, contact.boundaries) == ("tie", ("upper_bottom", "lower_top"))
    text = script(case)
    assert "contact = TieContact('upper_bottom', 'lower_top', name='contact').bind(problem)" in text
    compile(text, "tie.py", "exec")
    built = build(case)
    assert isinstance(built.variables["contact"], TieBarrier)
    rows = built.simulation.run()["rows"]
    assert rows[-1]["contact_force"][2] == pytest.approx(-rows[-1]["reaction_upper_top_Fz"], rel=1e-7)
    assert rows[-1]["reaction_upper_top_Fz"] == pytest.approx(0.0930774, rel=1e-5)
    assert rows[-1]["contact_max_gap"] < 1e-8


def test_friction_of_a_tool_reaches_the_script_and_the_columns(shared_tmp):
    """``friction`` on a tool: ToolContact(..., friction=0.2), and the column contact_friction_force."""
    folder = shared_tmp / "rough_tool"
    if MPI.COMM_WORLD.rank == 0:
        folder.mkdir(exist_ok=True)
    MPI.COMM_WORLD.Barrier()
    case = load_case(_write_tool(folder, TOOL.replace("dhat = 1e-3", "dhat = 1e-3\nfriction = 0.2", 1)),
                     output=folder / "out")
    assert "friction=0.2" in script(case)
    rows = build(case).simulation.run()["rows"]
    assert "contact_friction_force" in rows[-1]


# -- a tool's path through waypoints -------------------------------------------------------------------------------
RESTING = TOOL.replace("value = [-0.2]", "value = [0.0]")


def _braces(keys: str) -> str:
    """TOML inline tables in the case template (a str.format template)."""
    return keys.replace("{", "{{").replace("}", "}}")


def _tool_run(folder: Path, keys: str) -> tuple[str, list[dict]]:
    case = load_case(_write_tool(folder, RESTING.replace("dhat = 1e-3", f"dhat = 1e-3\n{_braces(keys)}", 1)),
                     output=folder / "out")
    text = script(case)
    summary = build(case).simulation.run()
    assert summary["completed"]
    return text, summary["rows"]


def test_tool_path_equals_motion_and_slides_without_friction(shared_tmp):
    """``path = {times, points}`` (hf.loading.Waypoints): the plate pushed up 0.1 into the resting block by a path
    equals the same push by ``motion`` (to round-off; 4 steps: the block's bottom is carried by the predictor, as the
    thin plate would pass through it); pushed, then slid 0.2 sideways, the frictionless plate presses with the same
    normal force to 6e-5 and a lateral force of 7e-5 of it (measured: the edge-edge pairs of a plate whose diagonal
    is parallel to the block's x = y edges, see tests/test_contact_surfaces.py)."""
    text, by_path = _tool_run(shared_tmp, "path = {times = [0.0, 1.0], points = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]]}")
    assert "motion=Waypoints(times=(0.0, 1.0), points=((0.0, 0.0, 0.0), (0.0, 0.0, 0.1)))" in " ".join(text.split())
    compile(text, "block_on_tool.py", "exec")
    _, by_motion = _tool_run(shared_tmp, "motion = [0.0, 0.0, 0.1]")
    for a, b in zip(by_path[1:], by_motion[1:], strict=True):
        assert a["contact_force"] == pytest.approx(b["contact_force"], rel=1e-10, abs=1e-14)
    pushed = by_path[-1]["contact_force"]
    assert pushed[2] > 0.05
    _, slid = _tool_run(shared_tmp, "path = {times = [0.0, 0.5, 1.0], points = "
                                    "[[0.0, 0.0, 0.0], [0.0, 0.0, 0.1], [0.2, 0.0, 0.1]]}")
    assert len(by_path) == len(slid) == 5  # the start and 4 steps
    assert slid[-1]["contact_force"][2] == pytest.approx(pushed[2], rel=1e-3)
    assert abs(slid[-1]["contact_force"][0]) < 1e-3 * pushed[2]


@pytest.mark.parametrize(
    "keys, expected",
    [
        ("path = {times = [0.0, 1.0], points = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]]}\nmotion = [0.0, 0.0, 0.1]",
         "contact[0].path: give either path or motion, not both"),
        ("path = {times = [0.0, 1.0], points = [[0.0, 0.0], [0.0, 0.0, 0.1]]}",
         "contact[0].path.points: one [x, y, z] (or [x, y] on a 2D mesh) per time, got rows of [2, 3]"),
        ("path = {times = [1.0, 0.0], points = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]]}",
         "contact[0].path: times must increase strictly, got [1.0, 0.0]"),
        ("path = {times = [0.0, 1.0]}", "contact[0].path: missing required key 'points'"),
        ("path = [0.0, 1.0]", "contact[0].path: expected a table, got an array of 2"),
    ],
)
def test_bad_tool_paths_are_one_line(shared_tmp, keys, expected):
    with pytest.raises(CaseFileError) as info:
        load_case(_write_tool(shared_tmp, TOOL.replace("dhat = 1e-3", f"dhat = 1e-3\n{_braces(keys)}", 1)))
    message = str(info.value)
    assert expected in message and "\n" not in message


# -- a rigid obstacle that turns ------------------------------------------------------------------------------------
TURNED = {"rotation": {"axis": [0.0, 0.0, 1.0], "center": [0.5, 0.5, 0.0], "angle": 0.5, "profile": "linear"}}


def _checked(shared_tmp, contact: dict):
    import tomllib

    from hyperfem.app.casefile import check_case

    data = tomllib.loads(CASE.read_text())
    data["mesh"]["file"] = str(ROOT / "meshes" / "block_h0.34.msh")
    data["contact"][0] = {"boundary": "bottom"} | contact
    data["output"]["fields"] = []
    return check_case(data, shared_tmp / "turned.toml")


def test_turned_cylinder_and_tool_cases_print_and_build_the_rotation(shared_tmp):
    """``rotation = {axis, center, angle, profile}``: the script prints RigidRotation(axis, Scaled(profile, angle),
    center) and compiles; the bound cylinder's axis is turned by the angle at t = 1; a tool takes it too; the
    rotation is part of the model hash."""
    from hyperfem.app.plan import model_hash

    case = _checked(shared_tmp, CYLINDER | TURNED)
    text = " ".join(script(case).split())
    assert ("rotation=RigidRotation((0.0, 0.0, 1.0), Scaled(linear_profile, 0.5), (0.5, 0.5, 0.0))") in text
    compile(script(case), "turned.py", "exec")
    built = build(dataclasses.replace(case, output=dataclasses.replace(case.output, directory=str(shared_tmp / "t"))))
    cylinder = built.variables["contact"].obstacle
    assert cylinder.axis_at(1.0) == pytest.approx([-np.sin(0.5), np.cos(0.5), 0.0], abs=1e-15)
    keys = _braces("rotation = {axis = [0, 0, 1], center = [1.0, 1.0, 0.0], angle = 0.3}")
    tool = load_case(_write_tool(shared_tmp, TOOL.replace("dhat = 1e-3", f"dhat = 1e-3\n{keys}", 1)))
    assert "rotation=RigidRotation((0.0, 0.0, 1.0), Scaled(linear_profile, 0.3), (1.0, 1.0, 0.0))" in " ".join(
        script(tool).split())
    plain = _checked(shared_tmp, CYLINDER)
    assert plain.contacts[0].rotation is None and model_hash(case) != model_hash(plain)


def test_turned_plane_case_prints_and_builds_the_rotation(shared_tmp):
    """A plane takes ``rotation`` too: the script prints it, the bound plane's normal is turned by the angle at
    t = 1 (a tilt of 0.02 about y through the bottom's middle, below the block)."""
    tilt = {"rotation": {"axis": [0.0, 1.0, 0.0], "center": [0.5, 0.5, -5e-4], "angle": 0.02}}
    case = _checked(shared_tmp, {"type": "plane", "point": [0.0, 0.0, -5e-4], "normal": [0.0, 0.0, 1.0]} | tilt)
    text = " ".join(script(case).split())
    assert "rotation=RigidRotation((0.0, 1.0, 0.0), Scaled(linear_profile, 0.02), (0.5, 0.5, -0.0005))" in text
    compile(script(case), "tilted.py", "exec")
    built = build(dataclasses.replace(case, output=dataclasses.replace(case.output, directory=str(shared_tmp / "p"))))
    plane = built.variables["contact"].obstacle
    assert plane.normal_at(1.0) == pytest.approx([np.sin(0.02), 0.0, np.cos(0.02)], abs=1e-15)


@pytest.mark.parametrize(
    "change, expected",
    [
        (CYLINDER | {"rotation": TURNED["rotation"] | {"axis": [0.0, 0.0, 0.0]}}, "contact[0].rotation.axis: must not"),
        (CYLINDER | {"rotation": {"axis": [0.0, 0.0, 1.0], "center": [0.0, 0.0, 0.0]}},
         "contact[0].rotation: missing required key 'angle'"),
        (CYLINDER | {"rotation": TURNED["rotation"] | {"angle": float("nan")}},
         "contact[0].rotation.angle: must be a finite number"),
        (SPHERE | {"rotation": [0.0, 0.0, 1.0]}, "contact[0].rotation: expected a table"),
        (SPHERE | {"center": [0.5, -2.0], "motion": [0.0, 1.0]} | TURNED,
         "contact[0].rotation: a rotation needs a 3D sphere"),
        ({"type": "plane", "point": [0.0, -0.1], "normal": [0.0, 1.0]} | TURNED,
         "contact[0].rotation: a rotation needs a 3D plane"),
    ],
)
def test_bad_rotations_name_their_key(shared_tmp, change, expected):
    with pytest.raises(CaseFileError) as info:
        _checked(shared_tmp, change)
    message = str(info.value)
    assert expected in message and "\n" not in message
