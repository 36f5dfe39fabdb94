"""Surface editing from Python (python/src/surface.cpp, spacewarp/_handles.py): meshes welded from
soups, the cotangent Laplacian and mass, handle regions and the handles file, the linear, ARAP and
cage-subspace ARAP editors, and edit(). Properties with closed forms: translations and rigid
motions reproduced, energies that never increase, Dirichlet energies and areas of known shapes.
"""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import main_thread_stall, subdivided_cube  # noqa: E402

STRETCH = np.array([3.0, 1.0, 1.0])  # the bar [-3, 3] x [-1, 1] x [-1, 1]
AREA = 2 * (6 * 2) * 2 + 2 * (2 * 2)  # its surface area


def bar(n: int = 6) -> tuple[np.ndarray, list[list[int]]]:
    """The bar's vertices and outward quads, n x n per face of the cube it is stretched from."""
    vertices, quads = subdivided_cube(n)
    return vertices * STRETCH, quads


def rotation(axis, degrees: float) -> np.ndarray:
    """The rotation matrix (3, 3) about `axis` (Rodrigues)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    t = np.radians(degrees)
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


@pytest.fixture(scope="module")
def mesh():
    vertices, quads = bar()
    return spacewarp.weld_soup(spacewarp.Geometry(vertices, quads))


@pytest.fixture(scope="module")
def ends(mesh):
    """The constrained vertices: both end caps of the bar (x = -3 and x = 3)."""
    x = mesh.positions[:, 0]
    return np.flatnonzero((x < -2.99) | (x > 2.99)).astype(np.uint32)


@pytest.fixture(scope="module")
def cage_coordinates():
    """Mean-value coordinates of a subdivided box cage around the bar."""
    vertices, quads = subdivided_cube(2)
    return spacewarp.MeanValue(spacewarp.Cage(vertices * (STRETCH + 0.5), quads))


def size(mesh) -> float:
    p = mesh.positions
    return float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))


def editors(mesh, ends, cage_coordinates) -> dict:
    return {
        "laplacian": spacewarp.LinearEditor(mesh.positions, mesh.triangles, ends),
        "bilaplacian": spacewarp.LinearEditor(mesh.positions, mesh.triangles, ends,
                                              method="bilaplacian"),
        "arap": spacewarp.ArapEditor(mesh.positions, mesh.triangles, ends),
        "cage-arap": spacewarp.CageArapEditor(mesh.positions, mesh.triangles, cage_coordinates,
                                              ends),
    }


def positions_of(result) -> np.ndarray:
    return result if isinstance(result, np.ndarray) else result.positions


# ----------------------------------------------------------------------------------------------
# Meshes and operators


def test_weld_soup_welds_duplicated_vertices_of_a_closed_bar():
    vertices, quads = bar()
    # Every quad with its own four vertices, as an STL-like export writes them.
    soup = spacewarp.Geometry(vertices[np.ravel(quads)], np.arange(4 * len(quads)).reshape(-1, 4))
    mesh = spacewarp.weld_soup(soup)
    assert mesh.vertex_count == len(vertices)
    assert mesh.triangles.shape == (2 * len(quads), 3) and mesh.triangles.dtype == np.uint32
    np.testing.assert_array_equal(mesh.positions[mesh.soup_to_mesh], soup.positions)
    np.testing.assert_array_equal(mesh.triangle_to_polygon, np.repeat(np.arange(len(quads)), 2))
    report = mesh.report
    assert report.is_manifold and report.boundary_edges == 0 and report.component_count == 1
    assert len(report.dropped_polygons) == 0 and len(report.isolated_vertices) == 0
    np.testing.assert_array_equal(mesh.vertex_component, 0)
    moved = mesh.positions + [1.0, 2.0, 3.0]
    np.testing.assert_array_equal(mesh.to_soup_positions(moved), soup.positions + [1.0, 2.0, 3.0])
    assert not mesh.positions.flags.writeable  # a view of the mesh, not a copy to change
    assert mesh.to_soup().polygon_count == len(mesh.triangles)


def test_weld_soup_reports_a_non_manifold_edge_and_the_boundary():
    # Three triangles on the edge (0, 1), each with its own copies of the edge's vertices.
    a, b = [0.0, 0, 0], [1.0, 0, 0]
    apexes = [[0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]]
    soup = spacewarp.Geometry([p for apex in apexes for p in (a, b, apex)],
                              np.arange(9).reshape(3, 3))
    mesh = spacewarp.weld_soup(soup)
    assert mesh.vertex_count == 5
    edge = sorted(mesh.soup_to_mesh[:2])
    np.testing.assert_array_equal(mesh.report.non_manifold_edges, [edge])
    assert mesh.report.non_manifold_edges.shape == (1, 2)
    assert mesh.report.boundary_edges == 6 and not mesh.report.is_manifold


def test_cotan_laplacian_is_symmetric_with_zero_row_sums(mesh):
    laplacian = spacewarp.cotan_laplacian(mesh.positions, mesh.triangles)
    assert laplacian.format == "csc" and laplacian.shape == (mesh.vertex_count,) * 2
    dense = laplacian.toarray()
    np.testing.assert_allclose(dense, dense.T, atol=1e-12)
    np.testing.assert_allclose(dense.sum(axis=1), 0.0, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(dense) > -1e-10)  # positive semi-definite


def test_dirichlet_energy_of_a_linear_function_is_the_area_times_its_gradient_squared():
    # A flat, irregular grid over [0, 2] x [0, 1.5]: f = x (|grad f| = 1) has x^T L x = area,
    # f = 2x - 3y has 13 x area, exactly for piecewise-linear functions.
    nx, ny = 9, 7
    u, v = np.meshgrid(np.linspace(0, 2, nx), np.linspace(0, 1.5, ny), indexing="ij")
    rng = np.random.default_rng(3)
    inner = (u > 0) & (u < 2) & (v > 0) & (v < 1.5)
    u = u + inner * rng.uniform(-0.05, 0.05, u.shape)
    v = v + inner * rng.uniform(-0.05, 0.05, v.shape)
    positions = np.c_[u.ravel(), v.ravel(), np.zeros(nx * ny)]
    index = np.arange(nx * ny).reshape(nx, ny)
    triangles = [t for i in range(nx - 1) for j in range(ny - 1)
                 for t in ([index[i, j], index[i + 1, j], index[i + 1, j + 1]],
                           [index[i, j], index[i + 1, j + 1], index[i, j + 1]])]
    laplacian = spacewarp.cotan_laplacian(positions, np.array(triangles))
    x, y = positions[:, 0], positions[:, 1]
    assert x @ (laplacian @ x) == pytest.approx(3.0, rel=1e-12)
    f = 2 * x - 3 * y
    assert f @ (laplacian @ f) == pytest.approx(13 * 3.0, rel=1e-12)
    mass = spacewarp.mass_matrix_diagonal(positions, triangles)
    assert mass.shape == (nx * ny,) and np.all(mass > 0)
    assert mass.sum() == pytest.approx(3.0, rel=1e-12)


def test_mass_sums_to_the_surface_area(mesh):
    mass = spacewarp.mass_matrix_diagonal(mesh.positions, mesh.triangles)
    assert np.all(mass > 0)
    assert mass.sum() == pytest.approx(AREA, rel=1e-12)
    scaled = spacewarp.mass_matrix_diagonal(2.5 * mesh.positions, mesh.triangles)
    np.testing.assert_allclose(scaled, 2.5**2 * mass, rtol=1e-12)


# ----------------------------------------------------------------------------------------------
# Handle regions


def test_resolve_handles_applies_matrices_by_rows_and_sorts(mesh):
    rest = mesh.positions
    matrix = np.eye(4)
    matrix[:3, :3] = rotation([0, 0, 1], 30)
    matrix[:3, 3] = [0.5, -1, 2]  # the translation is the last column of the rows
    regions = [{"vertices": [7, 3], "matrix": matrix.tolist()},
               {"vertices": np.array([1]), "targets": [[9.0, 8, 7]]}]
    vertices, targets = spacewarp.resolve_handles(regions, rest)
    assert vertices.dtype == np.uint32
    np.testing.assert_array_equal(vertices, [1, 3, 7])
    np.testing.assert_allclose(targets[0], [9, 8, 7])
    np.testing.assert_allclose(targets[1:], rest[[3, 7]] @ matrix[:3, :3].T + matrix[:3, 3],
                               atol=1e-14)


@pytest.mark.parametrize("regions, match", [
    ([{"vertices": [0, 10_000], "matrix": np.eye(4)}], "out of range"),
    ([{"vertices": [0], "targets": [[0.0, 0, 0], [1, 1, 1]]}], "1 vertices but 2 targets"),
    ([{"vertices": [0], "targets": [[np.nan, 0, 0]]}], "not finite"),
    ([{"vertices": [0], "matrix": np.ones((4, 4))}], "not affine"),
    ([{"vertices": [0], "matrix": np.eye(4), "targets": [[0.0, 0, 0]]}], "not both"),
    ([{"vertices": [0], "matrix": np.eye(4), "weight": 1}], "unknown key 'weight'"),
    ([{"matrix": np.eye(4)}], "no 'vertices'"),
    ([{"vertices": [0], "matrix": np.eye(3)}], r"regions\[0\].matrix must be 4 rows of 4"),
    ([{"vertices": [0, -1], "matrix": np.eye(4)}], r"regions\[0\].vertices\[1\]: index -1"),
    ([{"vertices": [0.5], "matrix": np.eye(4)}], r"vertices\[0\]: 0.5 is not an integer"),
    ([{"vertices": np.array([0.0]), "matrix": np.eye(4)}], "must be integers, not float64"),
    ([{"vertices": [2**70], "matrix": np.eye(4)}],
     r"vertices\[0\]: index 1180591620717411303424 is too large"),
    ([{"vertices": [0], "matrix": np.eye(4)}, {"vertices": [0], "targets": [[5.0, 5, 5]]}],
     "conflicting targets"),
])
def test_resolve_handles_errors_name_the_entry(mesh, regions, match):
    with pytest.raises(spacewarp.InvalidInput, match=match):
        spacewarp.resolve_handles(regions, mesh.positions)


def test_resolve_handles_refuses_what_is_not_a_list_of_dicts(mesh):
    with pytest.raises(TypeError, match=r"regions\[0\] must be a dict"):
        spacewarp.resolve_handles([[0, 1]], mesh.positions)
    with pytest.raises(TypeError, match="regions must be a list"):
        spacewarp.resolve_handles({"vertices": [0], "matrix": np.eye(4)}, mesh.positions)


def test_load_handles_reads_the_cli_format(tmp_path, mesh):
    matrix = np.eye(4)
    matrix[:3, 3] = [1, 2, 3]
    path = tmp_path / "handles.json"
    path.write_text(json.dumps({"handles": [
        {"vertices": [0, 1], "matrix": matrix.tolist()},
        {"vertices": [5], "targets": [[0.5, 0.25, 0.125]]}]}))
    regions = spacewarp.load_handles(path)
    assert len(regions) == 2
    np.testing.assert_array_equal(regions[0]["vertices"], [0, 1])
    np.testing.assert_array_equal(regions[0]["matrix"], matrix)
    np.testing.assert_array_equal(regions[1]["targets"], [[0.5, 0.25, 0.125]])
    vertices, targets = spacewarp.resolve_handles(regions, mesh.positions)
    np.testing.assert_array_equal(vertices, [0, 1, 5])
    np.testing.assert_allclose(targets[:2], mesh.positions[:2] + [1, 2, 3])


# The messages are those of `spacewarp edit --handles` (the same C++ reader).
@pytest.mark.parametrize("content, error, match", [
    ('{"handles": [{"vertices": [0, 1, -2], "matrix": []}]}', spacewarp.InvalidInput,
     r"h.json: handles\[0\].vertices\[2\]: must be a vertex index \(a whole number from 0\), "
     "not -2"),
    ('{"handles": [{"vertices": [0], "targets": [[0, 0, 0]]}, {"vertices": [1, "a"], '
     '"targets": []}]}', spacewarp.InvalidInput,
     r'handles\[1\].vertices\[1\]: must be a vertex index .*, not "a"'),
    ('{"handles": [{"vertices": [0], "matrix": [[1, 0, 0, 0]], "targets": [[0, 0, 0]]}]}',
     spacewarp.InvalidInput, r"handles\[0\]: has both 'matrix' and 'targets': give one"),
    ('{"handles": [{"vertices": [0], "matrix": [[1, 0, 0, 0]]}]}', spacewarp.InvalidInput,
     r"handles\[0\].matrix: must be an array of 4 rows of 4 numbers"),
    ('{"handles": [{"vertices": [0], "targets": [[0, 0]]}]}', spacewarp.InvalidInput,
     r"handles\[0\].targets\[0\]: must be an array of 3 numbers"),
    ('{"handles": []}', spacewarp.InvalidInput, "handles: must be a non-empty array"),
    ('{"handle": []}', spacewarp.InvalidInput, r"handle: is not a key here \(the keys: handles\)"),
    ('{"handles": [{"vertices": [0], "targets": [[NaN, 0, 0]]}]}', spacewarp.IoError,
     "h.json: not valid JSON: line 1, column 45"),
    ('{"handles": [', spacewarp.IoError, "h.json: not valid JSON: line 1"),
    ('{"handles": [], "handles": []}', spacewarp.InvalidInput, "'handles' is given twice"),
])
def test_load_handles_errors_name_the_file_and_key_path(tmp_path, content, error, match):
    path = tmp_path / "h.json"
    path.write_text(content)
    with pytest.raises(error, match=match):
        spacewarp.load_handles(path)


def test_load_handles_of_a_missing_file_is_an_io_error(tmp_path):
    with pytest.raises(spacewarp.IoError, match="missing.json: cannot open the handles file"):
        spacewarp.load_handles(tmp_path / "missing.json")


# ----------------------------------------------------------------------------------------------
# Editors


def test_a_common_translation_is_reproduced_by_every_editor(mesh, ends, cage_coordinates):
    shift = np.array([0.3, -0.2, 0.5])
    expected = mesh.positions + shift
    for name, editor in editors(mesh, ends, cage_coordinates).items():
        moved = positions_of(editor.solve(mesh.positions[ends] + shift))
        assert np.abs(moved - expected).max() < 1e-9 * size(mesh), name


@pytest.mark.parametrize("energy", ["spokes_and_rims", "spokes"])
def test_a_common_rigid_motion_is_reproduced_by_arap_and_cage_arap(mesh, ends, cage_coordinates,
                                                                   energy):
    r, shift = rotation([1, 1, 0.5], 70), np.array([1.0, -2.0, 0.5])
    expected = mesh.positions @ r.T + shift
    arap = spacewarp.ArapEditor(mesh.positions, mesh.triangles, ends, energy=energy)
    result = arap.solve(expected[ends])
    assert result.report.started_rigid
    assert np.abs(result.positions - expected).max() < 1e-9 * size(mesh)
    cage = spacewarp.CageArapEditor(mesh.positions, mesh.triangles, cage_coordinates, ends,
                                    energy=energy)
    posed = cage.solve(expected[ends])
    assert np.abs(posed.positions - expected).max() < 1e-9 * size(mesh)
    rest_cage = cage_coordinates.rest_control_points
    assert np.abs(posed.control_points - (rest_cage @ r.T + shift)).max() < 1e-9 * size(mesh)
    assert len(posed.report.unreached) == 0 and posed.report.max_residual < 1e-9 * size(mesh)


def test_linear_editing_cannot_follow_a_rotation_that_arap_follows(mesh, ends):
    r = rotation([0, 0, 1], 90)
    expected = mesh.positions @ r.T
    arap = spacewarp.ArapEditor(mesh.positions, mesh.triangles, ends).solve(expected[ends])
    assert np.abs(arap.positions - expected).max() < 1e-9 * size(mesh)
    for method in ("laplacian", "bilaplacian"):
        linear = spacewarp.LinearEditor(mesh.positions, mesh.triangles, ends, method=method)
        error = np.abs(linear.solve(expected[ends]) - expected).max()
        assert error > 0.01 * size(mesh), (method, error)


def bend_targets(mesh, ends, degrees: float = 60) -> np.ndarray:
    """The right end cap turned about z by `degrees` about its centre, the left one pinned."""
    rest = mesh.positions[ends]
    right = rest[:, 0] > 0
    centre = np.array([3.0, 0, 0])
    targets = rest.copy()
    targets[right] = (rest[right] - centre) @ rotation([0, 0, 1], degrees).T + centre
    return targets


def test_arap_energies_never_increase_and_solve_from_continues(mesh, ends):
    # The plain iteration (no acceleration) runs every one of max_iterations with tolerance 0.
    editor = spacewarp.ArapEditor(mesh.positions, mesh.triangles, ends, max_iterations=40,
                                  relative_tolerance=0.0, acceleration_window=0)
    result = editor.solve(bend_targets(mesh, ends))
    energies = result.report.energies
    assert result.report.iterations == 40 and len(energies) == 41
    assert energies[-1] < energies[0]
    assert np.all(np.diff(energies) <= 1e-12 * energies[0])
    assert editor.energy(result.positions) == pytest.approx(energies[-1], rel=1e-9)
    np.testing.assert_allclose(result.positions[ends], bend_targets(mesh, ends), atol=1e-12)
    again = editor.solve_from(result.positions, bend_targets(mesh, ends))
    assert again.report.energies[0] == pytest.approx(energies[-1], rel=1e-9)
    assert again.report.energies[-1] <= energies[-1] * (1 + 1e-12)
    # Zero at rest, to the rounding of the energy's per-element sums.
    assert abs(editor.energy(mesh.positions)) < 1e-12 * energies[0]


def test_cage_arap_energies_never_increase(mesh, ends, cage_coordinates):
    editor = spacewarp.CageArapEditor(mesh.positions, mesh.triangles, cage_coordinates, ends,
                                      rotation_clusters=32, max_iterations=25,
                                      relative_tolerance=0.0)
    assert editor.cluster_count == 32
    result = editor.solve(bend_targets(mesh, ends))
    energies = result.report.energies
    assert len(energies) == result.report.iterations + 1 and energies[-1] < energies[0]
    assert np.all(np.diff(energies) <= 1e-12 * energies[0])
    assert result.control_points.shape == (cage_coordinates.control_point_count, 3)
    np.testing.assert_allclose(result.positions,
                               cage_coordinates.bind(mesh.positions).deform(result.control_points),
                               atol=1e-12 * size(mesh))
    assert result.report.handle_residuals.shape == (len(ends),)
    assert result.report.max_residual == pytest.approx(result.report.handle_residuals.max())
    again = editor.solve_from(result.control_points, bend_targets(mesh, ends))
    assert again.report.energies[0] == pytest.approx(energies[-1], rel=1e-9)


def test_editors_keep_components_no_handle_reaches_at_rest():
    vertices, quads = bar(2)
    far = vertices + [10.0, 0, 0]  # a second bar with no handle
    soup = spacewarp.Geometry(np.vstack([vertices, far]),
                              np.vstack([quads, np.array(quads) + len(vertices)]))
    mesh = spacewarp.weld_soup(soup)
    assert mesh.report.component_count == 2
    constrained = np.flatnonzero(mesh.vertex_component == 0)[:5]
    targets = mesh.positions[constrained] + [0, 0, 1]
    for editor in (spacewarp.LinearEditor(mesh.positions, mesh.triangles, constrained),
                   spacewarp.ArapEditor(mesh.positions, mesh.triangles, constrained)):
        held = editor.held_vertices
        np.testing.assert_array_equal(held, np.flatnonzero(mesh.vertex_component == 1))
        moved = positions_of(editor.solve(targets))
        np.testing.assert_array_equal(moved[held], mesh.positions[held])


@pytest.mark.parametrize("name", ["laplacian", "bilaplacian", "arap", "cage-arap"])
def test_editor_errors_are_invalid_input(mesh, ends, cage_coordinates, name):
    editor = editors(mesh, ends, cage_coordinates)[name]
    targets = mesh.positions[ends].copy()
    targets[3, 1] = np.nan
    with pytest.raises(spacewarp.InvalidInput, match="not finite"):
        editor.solve(targets)
    with pytest.raises(spacewarp.InvalidInput, match="targets"):
        editor.solve(mesh.positions[ends][:-1])
    with pytest.raises(spacewarp.InvalidInput, match=r"shape \(n, 3\)"):
        editor.solve(mesh.positions[ends][:, :2])


def test_editor_construction_errors_are_invalid_input(mesh, ends, cage_coordinates):
    p, t = mesh.positions, mesh.triangles
    out_of_range = np.append(ends, mesh.vertex_count)
    with pytest.raises(spacewarp.InvalidInput, match=str(mesh.vertex_count)):
        spacewarp.ArapEditor(p, t, out_of_range)
    with pytest.raises(spacewarp.InvalidInput, match=str(mesh.vertex_count)):
        spacewarp.LinearEditor(p, t, out_of_range)
    with pytest.raises(spacewarp.InvalidInput, match=r"constrained\[0\]: index -1 is negative"):
        spacewarp.LinearEditor(p, t, [-1, 2])
    with pytest.raises(spacewarp.InvalidInput, match="no constrained vertex"):
        spacewarp.ArapEditor(p, t, [])
    with pytest.raises(spacewarp.InvalidInput, match="'laplacian' or 'bilaplacian'"):
        spacewarp.LinearEditor(p, t, ends, method="arap")
    with pytest.raises(spacewarp.InvalidInput, match="triangle 0 has 4"):
        spacewarp.ArapEditor(p, [[0, 1, 2, 3]], ends)
    with pytest.raises(spacewarp.InvalidInput):
        spacewarp.CageArapEditor(p, t, cage_coordinates, ends, handle_weight=-1.0)
    with pytest.raises(TypeError):
        spacewarp.CageArapEditor(p, t, "mvc", ends)


def test_a_progress_callable_returning_false_cancels(mesh, ends, cage_coordinates):
    editor = spacewarp.ArapEditor(mesh.positions, mesh.triangles, ends, max_iterations=50,
                                  relative_tolerance=0.0, acceleration_window=0)
    calls = []

    def stop_at_third(stage, fraction):
        calls.append((stage, fraction))
        return len(calls) < 3

    with pytest.raises(spacewarp.Cancelled):
        editor.solve(bend_targets(mesh, ends), progress=stop_at_third)
    assert len(calls) == 3 and calls[0][0] == "arap"
    # The editor is usable after a cancel.
    assert editor.solve(bend_targets(mesh, ends)).report.iterations == 50
    with pytest.raises(spacewarp.Cancelled):
        spacewarp.CageArapEditor(mesh.positions, mesh.triangles, cage_coordinates, ends,
                                 progress=lambda stage, fraction: False)
    raised = ZeroDivisionError("from the callable")

    def raising(stage, fraction):
        raise raised

    with pytest.raises(ZeroDivisionError) as info:
        editor.solve(bend_targets(mesh, ends), progress=raising)
    assert info.value is raised


def test_threads_share_one_editor(mesh, ends):
    editor = spacewarp.ArapEditor(mesh.positions, mesh.triangles, ends, max_iterations=10,
                                  relative_tolerance=0.0)
    targets = [bend_targets(mesh, ends, degrees) for degrees in (20, 40, 60, 80)]
    expected = [editor.solve(t).positions.copy() for t in targets]
    results: dict = {}
    barrier = threading.Barrier(len(targets))

    def run(i):
        barrier.wait()
        results[i] = editor.solve(targets[i]).positions

    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(targets))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not any(t.is_alive() for t in threads), "deadlock"
    for i in range(len(targets)):
        np.testing.assert_array_equal(results[i], expected[i])


def test_arap_releases_the_gil():
    vertices, quads = bar(40)  # 9,602 vertices, a few ms per iteration
    mesh = spacewarp.weld_soup(spacewarp.Geometry(vertices, quads))
    x = mesh.positions[:, 0]
    ends = np.flatnonzero((x < -2.99) | (x > 2.99))
    editor = spacewarp.ArapEditor(mesh.positions, mesh.triangles, ends, max_iterations=300,
                                  relative_tolerance=0.0)
    longest, duration = main_thread_stall(lambda: editor.solve(bend_targets(mesh, ends)))
    if duration < 0.2:
        pytest.skip(f"too fast here ({duration:.3f} s) to see the GIL")
    assert longest < duration / 3, f"main thread stalled {longest:.3f} s of {duration:.3f} s"


# ----------------------------------------------------------------------------------------------
# edit()


def flat_bar():
    """The bar as a flat-shaded soup: each quad with its own vertices and the face's normal."""
    vertices, quads = bar(4)
    corners = vertices[np.array(quads)]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return spacewarp.Geometry(corners.reshape(-1, 3), np.arange(4 * len(quads)).reshape(-1, 4),
                              normals=np.repeat(normals, 4, axis=0))


def end_regions(soup, matrix) -> list[dict]:
    x = soup.positions[:, 0]
    return [{"vertices": np.flatnonzero(x < -2.99), "matrix": matrix},
            {"vertices": np.flatnonzero(x > 2.99), "matrix": matrix}]


@pytest.mark.parametrize("method", ["laplacian", "bilaplacian", "arap", "cage-arap"])
def test_edit_reproduces_a_translation(method, cage_coordinates):
    soup = flat_bar()
    matrix = np.eye(4)
    matrix[:3, 3] = [0.25, 0.5, -1]
    options = {"coordinates": cage_coordinates} if method == "cage-arap" else {}
    edited = spacewarp.edit(soup, end_regions(soup, matrix), method=method, **options)
    assert edited is not soup
    np.testing.assert_array_equal(edited.faces, soup.faces)
    np.testing.assert_allclose(edited.positions, soup.positions + matrix[:3, 3], atol=1e-9 * 7)
    np.testing.assert_allclose(edited.normals, soup.normals, atol=1e-9)


def test_edit_turns_positions_and_flat_normals_with_a_rigid_motion():
    soup = flat_bar()
    matrix = np.eye(4)
    matrix[:3, :3] = rotation([0.2, 1, 0.4], 50)
    matrix[:3, 3] = [1, 2, 3]
    edited = spacewarp.edit(soup, end_regions(soup, matrix))
    np.testing.assert_allclose(edited.positions, soup.positions @ matrix[:3, :3].T + matrix[:3, 3],
                               atol=1e-9 * 7)
    # Welded vertices keep their own face's normal: the flat shading survives.
    np.testing.assert_allclose(edited.normals, soup.normals @ matrix[:3, :3].T, atol=1e-9)


def test_edit_refuses_options_the_method_does_not_use(cage_coordinates):
    soup = flat_bar()
    regions = end_regions(soup, np.eye(4))
    with pytest.raises(spacewarp.InvalidInput, match="max_iterations does not apply"):
        spacewarp.edit(soup, regions, method="laplacian", max_iterations=3)
    with pytest.raises(spacewarp.InvalidInput, match="handle_weight does not apply"):
        spacewarp.edit(soup, regions, method="arap", handle_weight=3.0)
    with pytest.raises(spacewarp.InvalidInput, match="needs coordinates"):
        spacewarp.edit(soup, regions, method="cage-arap")
    with pytest.raises(spacewarp.InvalidInput, match="coordinates does not apply"):
        spacewarp.edit(soup, regions, coordinates=cage_coordinates)
    with pytest.raises(spacewarp.InvalidInput, match="energy does not apply"):
        spacewarp.edit(soup, regions, method="bilaplacian", energy="spokes")
    with pytest.raises(spacewarp.InvalidInput, match="'spokes', not 'rims'"):
        spacewarp.edit(soup, regions, method="arap", energy="rims")
    with pytest.raises(spacewarp.InvalidInput, match="'cage-arap', not 'arapp'"):
        spacewarp.edit(soup, regions, method="arapp")
    with pytest.raises(spacewarp.InvalidInput, match=r"handles\[1\].vertices\[0\]"):
        spacewarp.edit(soup, [regions[0], {"vertices": [-4], "matrix": np.eye(4)}])


def test_edit_stops_when_its_progress_callable_returns_false():
    soup = flat_bar()
    matrix = np.eye(4)
    matrix[:3, :3] = rotation([0, 0, 1], 60)
    regions = end_regions(soup, np.eye(4))[:1] + end_regions(soup, matrix)[1:]
    stages = []
    with pytest.raises(spacewarp.Cancelled):
        spacewarp.edit(soup, regions, progress=lambda stage, fraction: stages.append(stage) or False)
    # The False at the start is seen after the first iteration (as every stage's first unit),
    # which reports again only if it completed a whole percent of max_iterations.
    assert stages in (["arap"], ["arap", "arap"])


def test_edit_warns_when_arap_does_not_converge():
    soup = flat_bar()
    matrix = np.eye(4)
    matrix[:3, :3] = rotation([0, 0, 1], 60)
    regions = end_regions(soup, np.eye(4))[:1] + end_regions(soup, matrix)[1:]
    with pytest.warns(UserWarning, match="ARAP did not converge in 2 iterations"):
        spacewarp.edit(soup, regions, max_iterations=2)


def corner_normals_of_obj(path) -> np.ndarray:
    """The normal of each polygon corner of an OBJ file, in face order (c, 3)."""
    normals, corners = [], []
    for line in path.read_text().splitlines():
        words = line.split()
        if words and words[0] == "vn":
            normals.append([float(w) for w in words[1:4]])
        elif words and words[0] == "f":
            corners += [int(w.split("/")[2]) - 1 for w in words[1:]]
    return np.array(normals)[corners]


def test_edit_turns_corner_normals_with_their_polygon(tmp_path):
    # A bar whose OBJ gives each face its own normal on the shared vertices (f v//n).
    vertices, quads = bar(2)
    corners = vertices[np.array(quads)]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices]
    lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in normals]
    lines += ["f " + " ".join(f"{v + 1}//{f + 1}" for v in quad) for f, quad in enumerate(quads)]
    (tmp_path / "bar.obj").write_text("\n".join(lines) + "\n")
    soup = spacewarp.read(tmp_path / "bar.obj")
    assert soup.normals is None  # the normals are per corner
    matrix = np.eye(4)
    matrix[:3, :3] = rotation([1, -0.3, 0.7], 35)
    matrix[:3, 3] = [0.5, 0, -2]
    edited = spacewarp.edit(soup, end_regions(soup, matrix))
    np.testing.assert_allclose(edited.positions, vertices @ matrix[:3, :3].T + matrix[:3, 3],
                               atol=1e-9 * 7)
    spacewarp.write(tmp_path / "edited.obj", edited)
    np.testing.assert_allclose(corner_normals_of_obj(tmp_path / "edited.obj"),
                               np.repeat(normals, 4, axis=0) @ matrix[:3, :3].T, atol=1e-9)


def test_edit_warns_of_unreached_handles_and_of_parts_no_handle_reaches():
    soup = flat_bar()
    x = soup.positions[:, 0]
    # The 8 corners of a box: a cage-subspace too small to bend the bar.
    box = spacewarp.Cage(np.array([[i, j, k] for k in (-1, 1) for j in (-1, 1) for i in (-1, 1)],
                                  float) * [3.5, 1.5, 1.5],
                         [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2],
                          [1, 3, 7, 5]])
    bend = np.eye(4)
    bend[:3, :3] = rotation([0, 0, 1], 90)
    regions = [{"vertices": np.flatnonzero(x < -2.99), "matrix": np.eye(4)},
               {"vertices": np.flatnonzero(x > 2.99), "matrix": bend}]
    with pytest.warns(UserWarning, match="handle vertices are left farther than reach_tolerance"):
        spacewarp.edit(soup, regions, method="cage-arap", coordinates=spacewarp.MeanValue(box))
    with pytest.warns(UserWarning, match="does not reproduce rotations exactly"):
        spacewarp.edit(soup, regions, method="cage-arap", coordinates=spacewarp.Green(box))
    # A second bar, apart, that no region touches.
    apart = spacewarp.Geometry(np.vstack([soup.positions, soup.positions + [10.0, 0, 0]]),
                               np.vstack([soup.faces, soup.faces + len(x)]))
    held = len(bar(4)[0])  # the second bar's vertices, welded
    with pytest.warns(UserWarning, match=f"^{held} mesh vertices are in parts no handle reaches"):
        edited = spacewarp.edit(apart, regions[:1] + [{"vertices": regions[1]["vertices"],
                                                       "matrix": np.eye(4)}], method="laplacian")
    np.testing.assert_array_equal(edited.positions, apart.positions)
