// SPDX-License-Identifier: GPL-3.0-or-later
//
// SSS Lab as a Flamenco 3 job type. Copy this file into the `scripts/` folder beside
// flamenco-manager and restart the Manager; "SSS Lab" then appears among the job types of the
// Blender add-on's submission panel.
//
// It mirrors the Open Job Description template farm/openjd/template.yaml task by task, with the same
// commands and arguments (tests/core/test_farm_jobs.py checks that):
//
//   render-CHUNK      {blender} {blenderArgs} --command sss_lab render BLENDFILE --out OUT/passes
//                       --frames CHUNK --methods M --pass-samples N [--resolution WxH] --threads T --device D
//                       --skip-existing
//   apply-CHUNK       NUMPY apply OUT/passes/passes_####.exr --frames CHUNK --methods M --skip-existing
//                       (after render-CHUNK)
//   reference-SEED    {blender} {blenderArgs} --command sss_lab reference BLENDFILE --out OUT/reference
//                       --seeds SEED --samples S --frames F [--resolution WxH] --threads T --device D
//                       --skip-existing
//   merge-reference   NUMPY merge-reference OUT/reference --out OUT/reference/reference.exr --overwrite
//                       (after every reference-SEED)
//   compare           {blender} {blenderArgs} --command sss_lab compare BLENDFILE --out OUT/compare --overwrite
//                       --reference OUT/reference/reference.exr --frames F --methods M --pass-samples N
//                       [--resolution WxH] --threads T --device D   (after merge-reference and every apply)
//
// The reference, merge and compare tasks exist only with "Compare" on. NUMPY is the setting
// "NumPy command" split at spaces: by default "{blender} --command sss_lab" (Flamenco workers have
// Blender); "python -m sss_lab" on workers with numpy and OpenEXR only.

const JOB_TYPE = {
  label: "SSS Lab",
  description: "Render SSS Lab's passes in frame chunks, apply the SSS techniques, optionally compare them "
    + "with a Cycles reference rendered over several tasks by seed",
  settings: [
    { key: "frames", type: "string", required: true, eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
      evalInfo: { showLinkButton: true, description: "Scene frame range" },
      description: "Frames to render, e.g. '47', '1-30', '3, 5-10, 47-327'" },
    { key: "chunk_size", type: "int32", default: 5, visible: "submission",
      description: "Frames per render and apply task" },
    { key: "output_root", type: "string", subtype: "dir_path", required: true, visible: "submission",
      description: "Folder for passes/, reference/ and compare/" },
    { key: "methods", type: "string", default: "all", visible: "submission",
      description: "Techniques: sta, ssss, burley, a comma-separated list, or all (STA needs a baked thickness map)" },
    { key: "pass_samples", type: "int32", default: 64, visible: "submission", description: "Cycles samples of the passes" },
    { key: "resolution", type: "string", default: "", visible: "submission",
      description: "WIDTHxHEIGHT for every render (empty: the scene's)" },
    { key: "threads", type: "int32", default: 0, visible: "submission", description: "Render threads (0: one per core)" },
    { key: "device", type: "string", default: "CPU", choices: ["CPU", "CUDA", "OPTIX", "HIP", "ONEAPI", "METAL"],
      visible: "submission", description: "Cycles device" },
    { key: "numpy_command", type: "string", default: "{blender} --command sss_lab", visible: "submission",
      description: "How the NumPy tasks (apply, merge) run SSS Lab, e.g. 'python -m sss_lab'" },
    { key: "compare", type: "bool", default: false, visible: "submission",
      description: "Also render the reference over several tasks and write the comparison report" },
    { key: "compare_eevee", type: "bool", default: true, visible: "submission",
      description: "Score EEVEE beside the techniques in the comparison (needs an OpenGL context on the worker)" },
    { key: "compare_frame", type: "int32", eval: "C.scene.frame_current", visible: "submission",
      description: "The frame the reference shows and the comparison measures" },
    { key: "reference_tasks", type: "int32", default: 8, visible: "submission",
      description: "Reference tasks, one seed each (seeds 1..N)" },
    { key: "reference_samples", type: "int32", default: 64, visible: "submission",
      description: "Cycles samples per reference task" },
    { key: "blendfile", type: "string", required: true, visible: "web", description: "The .blend scene" },
  ],
};

function compileJob(job) {
  const settings = job.settings;
  const out = settings.output_root;
  const passesDir = path.join(out, "passes");
  const referenceDir = path.join(out, "reference");
  const common = renderOptions(settings);

  const applyTasks = [];
  for (const chunk of frameChunker(settings.frames, settings.chunk_size)) {
    const render = blenderTask(`render-${chunk}`, "render", settings.blendfile, [
      "--out", passesDir, "--frames", chunk, "--methods", settings.methods, "--pass-samples", String(settings.pass_samples),
      ...common, "--skip-existing",
    ]);
    job.addTask(render);
    const apply = numpyTask(`apply-${chunk}`, settings, [
      "apply", path.join(passesDir, "passes_####.exr"), "--frames", chunk, "--methods", settings.methods,
      "--skip-existing",
    ]);
    apply.addDependency(render);
    job.addTask(apply);
    applyTasks.push(apply);
  }
  if (!settings.compare) {
    return;
  }
  const merged = path.join(referenceDir, "reference.exr");
  const merge = numpyTask("merge-reference", settings, ["merge-reference", referenceDir, "--out", merged, "--overwrite"]);
  for (let seed = 1; seed <= settings.reference_tasks; seed++) {
    const part = blenderTask(`reference-${seed}`, "reference", settings.blendfile, [
      "--out", referenceDir, "--seeds", String(seed), "--samples", String(settings.reference_samples),
      "--frames", String(settings.compare_frame), ...common, "--skip-existing",
    ]);
    job.addTask(part);
    merge.addDependency(part);
  }
  job.addTask(merge);
  const compare = blenderTask("compare", "compare", settings.blendfile, [
    "--out", path.join(out, "compare"), "--overwrite", "--reference", merged, "--frames", String(settings.compare_frame),
    "--methods", settings.methods,
    "--pass-samples", String(settings.pass_samples), ...common, ...(settings.compare_eevee ? [] : ["--no-eevee"]),
  ]);
  compare.addDependency(merge);
  for (const apply of applyTasks) {
    compare.addDependency(apply);
  }
  job.addTask(compare);
}

// --resolution (when set), --threads and --device: the options every Blender task shares.
function renderOptions(settings) {
  const options = [];
  if (settings.resolution) {
    options.push("--resolution", settings.resolution);
  }
  options.push("--threads", String(settings.threads), "--device", settings.device);
  return options;
}

// A Blender task: {blender} {blenderArgs} --command sss_lab COMMAND BLENDFILE ARGS...
function blenderTask(name, command, blendfile, args) {
  const task = author.Task(name, "blender");
  task.addCommand(author.Command("blender-render", {
    exe: "{blender}",
    exeArgs: "{blenderArgs}",
    argsBefore: ["--command", "sss_lab", command],
    blendfile: blendfile,
    args: args,
  }));
  return task;
}

// A NumPy-only task run by the "NumPy command" setting (split at spaces).
function numpyTask(name, settings, args) {
  const words = settings.numpy_command.split(" ").filter((w) => w.length > 0);
  const task = author.Task(name, "misc");
  task.addCommand(author.Command("exec", { exe: words[0], args: [...words.slice(1), ...args] }));
  return task;
}
