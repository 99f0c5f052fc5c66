// flamenco_harness.js: runs a Flamenco 3 job-type file the way the Manager's job compiler
// does, with the part of its API the job types use (author.Task, author.Command,
// frameChunker, path, print), and prints the compiled job as JSON.
//
//   node flamenco_harness.js JOB_TYPE.js SETTINGS.json
//
// Output: {"label": ..., "settings": [...keys], "tasks": [{name, type, commands: [{type,
// parameters}]}]} or {"error": "<what compileJob threw>"}.
"use strict";
const fs = require("fs");
const nodePath = require("path");
const vm = require("vm");

// Flamenco's frame chunker: "1-10,20" in chunks of _size_ -> ["1-4", "5-8", "9,10", "20"]-like
// ranges written "a-b" (or "a" for one frame), consecutive frames only.
function frameChunker(frames, size) {
    const list = [];
    for (const part of `${frames}`.split(",")) {
        const p = part.trim();
        if (p === "") continue;
        const m = p.match(/^(-?\d+)\s*-\s*(-?\d+)$/);
        if (m) {
            const a = parseInt(m[1], 10), b = parseInt(m[2], 10);
            if (b < a) throw `invalid frame range "${p}"`;
            for (let f = a; f <= b; f++) list.push(f);
        } else if (/^-?\d+$/.test(p)) {
            list.push(parseInt(p, 10));
        } else {
            throw `invalid frame range "${p}"`;
        }
    }
    const chunks = [];
    let start = 0;
    while (start < list.length) {
        let end = start;
        while (end + 1 < list.length && end + 1 - start < size && list[end + 1] === list[end] + 1) end++;
        chunks.push(list[start] === list[end] ? `${list[start]}` : `${list[start]}-${list[end]}`);
        start = end + 1;
    }
    return chunks;
}

function makeTask(name, type) {
    return {
        name, type, commands: [], dependencies: [],
        addCommand(cmd) { this.commands.push(cmd); },
        addDependency(task) { this.dependencies.push(task.name); },
    };
}

const [jobTypeFile, settingsFile] = process.argv.slice(2);
const settings = JSON.parse(fs.readFileSync(settingsFile, "utf8"));
const job = { settings, created: new Date(0), tasks: [], addTask(t) { this.tasks.push(t); } };
const context = vm.createContext({
    author: { Task: makeTask, Command: (type, parameters) => ({ type, parameters }) },
    frameChunker,
    path: { join: nodePath.join, dirname: nodePath.dirname, basename: nodePath.basename,
            stem: (p) => nodePath.basename(p, nodePath.extname(p)) },
    print: (...args) => console.error(...args),
    formatTimestampLocal: (d) => d.toISOString(),
});
vm.runInContext(fs.readFileSync(jobTypeFile, "utf8") + "\n;this.JOB_TYPE = JOB_TYPE; this.compileJob = compileJob;",
                context, { filename: jobTypeFile });
const out = { label: context.JOB_TYPE.label, settings: context.JOB_TYPE.settings.map((s) => s.key) };
try {
    context.compileJob(job);
    out.tasks = job.tasks.map((t) => ({ name: t.name, type: t.type, commands: t.commands,
                                        dependencies: t.dependencies }));
} catch (e) {
    out.error = `${e}`;
}
console.log(JSON.stringify(out));
