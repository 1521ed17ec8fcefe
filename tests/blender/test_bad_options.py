"""Options that used to end in a traceback after work had started."""

import os
import re

import pytest

from sss_lab.blender.compare import CompareSettings


@pytest.mark.parametrize(("resolution", "box"), [((1, 1), 2), ((64, 3), 4)])
def test_compare_refuses_a_resolution_smaller_than_its_box(resolution, box):
    settings = CompareSettings(resolution=resolution, box=box)
    with pytest.raises(ValueError, match=rf"smaller than the {box}x{box} box"):
        settings.validate()
    CompareSettings(resolution=(box, box), box=box).validate()  # the smallest that has a pixel to measure


def _save(tmp_path, name, build):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    build(bpy)
    path = tmp_path / name
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def _flat_mesh(bpy):
    mesh = bpy.data.meshes.new("Line")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (2, 0, 0)], [], [(0, 1, 2)])  # a face of zero area
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("Line", mesh))


def test_a_bake_that_bakes_nothing_says_why_and_writes_nothing(tmp_path, capsys):
    from sss_lab.addon import cli

    blend = _save(tmp_path, "flat.blend", _flat_mesh)
    out = tmp_path / "baked.blend"
    code = cli.main(["bake-thickness", str(blend), "--out", str(out), "--samples", "4", "--objects", "Line"])
    captured = capsys.readouterr()
    assert code == 2 and not out.exists()
    assert "Line: skipped" in captured.out  # the reason, per object
    assert "nothing was baked (1 skipped" in captured.err and captured.err.count("\n") == 1


def _cube_with_sss(bpy):
    from sss_lab.blender import compat

    bpy.ops.wm.read_factory_settings(use_empty=False)
    material = bpy.data.materials.new("Skin")
    compat.ensure_node_tree(material)
    material.node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 1.0
    bpy.data.objects["Cube"].data.materials[0] = material  # the faces use slot 0


def test_render_refuses_a_folder_where_a_sidecar_goes_before_rendering(tmp_path, capsys):
    from sss_lab.addon import cli

    blend = _save(tmp_path, "cube.blend", _cube_with_sss)
    out = tmp_path / "passes"
    (out / "passes_0001.json").mkdir(parents=True)
    argv = ["render", str(blend), "--out", str(out), "--frames", "1", "--resolution", "16x16", "--pass-samples", "2"]
    code = cli.main([*argv, "--methods", "ssss,burley", "--overwrite"])
    err = capsys.readouterr().err
    assert code == 2 and "passes_0001.json is a folder or not a regular file" in err
    assert sorted(os.listdir(out)) == ["passes_0001.json"]  # nothing rendered, nothing half-written


def test_compare_warns_about_a_kernel_far_beyond_the_object_and_still_scatters(tmp_path):
    # Subsurface Scale 1000 times too large (a units slip): the rows used to equal "no SSS".
    import bpy

    from sss_lab.blender.compare import CompareSettings, compare

    _cube_with_sss(bpy)
    node = bpy.data.materials["Skin"].node_tree.nodes["Principled BSDF"]
    node.inputs["Subsurface Scale"].default_value = 50.0
    settings = CompareSettings(
        resolution=(24, 24),
        reference_samples=4,
        pass_samples=4,
        peer_samples=(),
        cycles_burley=False,
        techniques=("ssss", "burley"),
        qualities={"ssss": ({},), "burley": ({},)},
        eevee=False,
    )
    lines = []
    data = compare(bpy.context.scene, str(tmp_path / "report"), settings, log=lines.append)
    assert any("Burley: warning: material 'Skin'" in x and "Subsurface Scale" in x for x in lines), lines
    rows = {e["name"]: e["metrics"]["rel_rmse"] for e in data["entries"]}
    assert rows["Burley"] != rows["no SSS"] and rows["SSSS"] != rows["no SSS"]


def test_compare_refuses_a_folder_holding_an_earlier_report_without_overwrite(tmp_path, capsys):
    """An earlier metrics.json was lost when compare ran again into its folder: refused before the
    .blend is even opened, unless --overwrite says to replace it."""
    from sss_lab.addon import cli

    out = tmp_path / "report"
    out.mkdir()
    (out / "metrics.json").write_text("{}")
    code = cli.main(["compare", str(tmp_path / "missing.blend"), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "holds the report of an earlier comparison (metrics.json)" in err
    assert (out / "metrics.json").read_text() == "{}"
    # With --overwrite the check passes (and the missing .blend is the next error).
    assert cli.main(["compare", str(tmp_path / "missing.blend"), "--out", str(out), "--overwrite"]) == 2
    assert "missing.blend" in capsys.readouterr().err


def test_compare_counts_its_steps_and_says_every_file_it_wrote(tmp_path, capsys):
    from sss_lab.addon import cli
    from sss_lab.blender.samples import load_sample_scenes

    blend = load_sample_scenes().build("head_frontlit", str(tmp_path / "head.blend"))
    out = tmp_path / "report"
    argv = ["compare", blend, "--out", str(out), "--resolution", "24x24", "--reference-samples", "4"]
    assert cli.main([*argv, "--pass-samples", "2", "--methods", "burley", "--no-eevee"]) == 0
    printed = capsys.readouterr().out
    steps = re.findall(r"^compare: \[(\d+)/(\d+)\] .+\((.+)\)$", printed, flags=re.MULTILINE)
    assert [int(k) for k, _, _ in steps] == list(range(1, len(steps) + 1)) and steps[-1][0] == steps[-1][1]
    assert all("ETA" in status for _, _, status in steps[1:])
    saved = re.findall(r"^Saved: '(.+)'$", printed, flags=re.MULTILINE)
    for name in ("metrics.json", "report.md", "report.html", "summary.png", "grid.png", "pareto.svg"):
        assert str(out / name) in saved, name
    assert all(os.path.isfile(p) for p in saved)
