// SPDX-License-Identifier: GPL-3.0-or-later
// airlight_render.js: a Flamenco 3 job type that renders frames with Airlight's fog.
//
// Install: copy this file into the Flamenco Manager's `scripts/` folder and restart it;
// "Airlight Render" then appears in Blender's Flamenco add-on next to the built-in types.
// Every worker needs the Airlight add-on installed in the Blender user folder the worker's
// Blender uses (docs/farm.md). Each render task first checks, in the same Blender process,
// that the add-on and its compiled module loaded; if not, Blender exits 1 and Flamenco marks
// the task failed with the reason in its log, rather than rendering unfogged frames.
// A frame whose fog bake fails prints "rendered without fog" in the task log.

const JOB_TYPE = {
    label: "Airlight Render",
    description: "Render frames with Airlight's baked fog (fails any task whose worker lacks the add-on)",
    settings: [
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          evalInfo: { showLinkButton: true, description: "Scene frame range" },
          description: "Frame range to render. Examples: '47', '1-30', '3, 5-10, 47-327'" },
        { key: "chunk_size", type: "int32", default: 1, propargs: { min: 1 },
          description: "Number of frames to render in one Blender render task", visible: "submission" },
        { key: "render_output_root", type: "string", subtype: "dir_path", required: true, visible: "submission",
          description: "Base directory of where render output is stored" },
        { key: "render_output_path", type: "string", subtype: "file_path", editable: false,
          eval: "str(Path(abspath(settings.render_output_root), jobname, '######'))",
          description: "Final file path of where render output will be saved" },
        { key: "blendfile", type: "string", required: true, description: "Path of the Blend file to render",
          visible: "web" },
        { key: "format", type: "string", required: true, eval: "C.scene.render.image_settings.file_format",
          visible: "web" },
    ],
};

// Run inside the task's Blender after the file loads (--python-exit-code 1: an exception
// here exits 1 before anything renders).
const ADDON_CHECK = [
    "import airlight",
    "from airlight import native",
    "assert native.available(), 'Airlight native module not loaded: ' + str(native.error())",
    "print('Airlight: add-on and native module loaded')",
].join("; ");

const VIDEO_FORMATS = ["FFMPEG", "AVI_RAW", "AVI_JPEG"];

function compileJob(job) {
    const settings = job.settings;
    if (!settings.frames || `${settings.frames}`.trim() === "") {
        throw "Airlight Render: no frames to render";
    }
    if (!(settings.chunk_size >= 1)) {
        throw `Airlight Render: chunk_size must be at least 1, got ${settings.chunk_size}`;
    }
    if (VIDEO_FORMATS.indexOf(settings.format) >= 0) {
        throw `Airlight Render renders images (the fog is composited per frame), not "${settings.format}"`;
    }
    if (!settings.render_output_path) {
        throw "Airlight Render: no render_output_path setting";
    }
    const renderOutput = settings.render_output_path;
    for (const chunk of frameChunker(settings.frames, settings.chunk_size)) {
        const task = author.Task(`render-${chunk}`, "blender");
        task.addCommand(author.Command("blender-render", {
            exe: "{blender}",
            exeArgs: "{blenderArgs}",
            argsBefore: ["--addons", "airlight"],
            blendfile: settings.blendfile,
            args: [
                "--python-exit-code", "1",
                "--python-expr", ADDON_CHECK,
                "--render-output", renderOutput,
                "--render-format", settings.format,
                "--render-frame", chunk.replaceAll("-", ".."),
            ],
        }));
        job.addTask(task);
    }
}
