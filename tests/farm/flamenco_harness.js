// Runs farm/flamenco/sss_lab.js the way Flamenco's Manager does (a script with JOB_TYPE and
// compileJob, given `author`, `path`, `frameChunker` and `print`), against a stub of that API
// that records the tasks. Usage: node flamenco_harness.js JOB_TYPE_FILE SETTINGS_JSON
// Prints {"label", "settings", "tasks": [{name, type, commands, dependencies}]} as JSON.
"use strict";
const fs = require("fs");
const vm = require("vm");
const nodePath = require("path");

const [file, settingsJson] = process.argv.slice(2);

// Flamenco's frameChunker: "1-5,8" with chunk size 2 -> ["1-2", "3-4", "5,8"] (a chunk is a
// run of consecutive frames as "a-b", single frames as "a", joined by commas).
function frameChunker(frames, chunkSize) {
  const numbers = [];
  for (const part of String(frames).split(",")) {
    const p = part.trim();
    if (!p) continue;
    const m = /^(-?\d+)(?:-(-?\d+))?$/.exec(p);
    if (!m) throw new Error(`frameChunker: bad frame range ${JSON.stringify(p)}`);
    const a = Number(m[1]);
    const b = m[2] === undefined ? a : Number(m[2]);
    for (let f = a; f <= b; f++) numbers.push(f);
  }
  const chunks = [];
  for (let i = 0; i < numbers.length; i += chunkSize) {
    const group = numbers.slice(i, i + chunkSize);
    const runs = [];
    let start = group[0];
    let prev = group[0];
    for (const f of group.slice(1).concat([null])) {
      if (f !== null && f === prev + 1) { prev = f; continue; }
      runs.push(start === prev ? `${start}` : `${start}-${prev}`);
      start = prev = f;
    }
    chunks.push(runs.join(","));
  }
  return chunks;
}

const tasks = [];
const created = new Set();
const author = {
  Task(name, type) {
    const task = {
      name, type, commands: [], dependencies: [],
      addCommand(cmd) { this.commands.push(cmd); },
      addDependency(other) {
        if (!created.has(other)) throw new Error(`${name}: addDependency needs a task made by author.Task`);
        this.dependencies.push(other.name);
      },
    };
    created.add(task);
    return task;
  },
  Command(name, parameters) { return { name, parameters }; },
};
const job = {
  settings: JSON.parse(settingsJson),
  addTask(task) {
    if (tasks.some((t) => t.name === task.name)) throw new Error(`two tasks named ${task.name}`);
    tasks.push(task);
  },
};

const sandbox = { author, frameChunker, path: nodePath.posix, print: (...a) => process.stderr.write(a.join(" ") + "\n"), job };
vm.createContext(sandbox);
vm.runInContext(fs.readFileSync(file, "utf8") + "\n;this.JOB_TYPE = JOB_TYPE; this.compileJob = compileJob;", sandbox, { filename: file });
sandbox.compileJob(job);
process.stdout.write(JSON.stringify({
  label: sandbox.JOB_TYPE.label,
  settings: sandbox.JOB_TYPE.settings,
  tasks: tasks.map(({ name, type, commands, dependencies }) => ({ name, type, commands, dependencies })),
}));
