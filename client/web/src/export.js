// The Export menu and the GLB import (issue 39, docs/model-format.md, docs/print.md): the model
// taken out through the proxy's one export path, GET /v1/sessions/{id}/export?format=glb|stl|3mf
// (the scene with every stroke's pen data, or the print as one closed solid in millimetres),
// with a bar of each stage's steps while the proxy makes the file (its progress lines); and a GLB penmesh exported brought back, chosen in the menu or dropped on the
// page (POST /v1/sessions/{id}/import with this tab's participant key: its strokes come back as
// this tab's, and arrive live as any new stroke). Builds its own menu; needs only a button.
import { DEFAULT_PRINT_MM } from "./scene.js";

const FORMATS = [
  ["glb", "GLB scene", "every stroke as a node with its pen data: Blender, three.js, back into penmesh"],
  ["stl", "STL print", "one closed solid in millimetres, for a slicer"],
  ["3mf", "3MF print", "the same solid as a 3MF package (unit mm)"],
];

/// Wires the Export menu to `button`. `token` opens the session, `key()` is this tab's
/// participant key, `name()` its display name; `notice` and `fail` report to the person;
/// `imported(ids)` is told the strokes an import made (the history makes them one undo step);
/// `printSize(mm)` the print's longest side whenever it is changed (the page's mm follow it).
/// Returns `{ exportModel(format, sizeMm), importFile(file) }` for the tests and the curious.
export function attachExport({ button, session, token, key, name, notice, fail, imported = () => {}, printSize = () => {} }) {
  const dialog = document.createElement("dialog");
  dialog.id = "export-menu";
  dialog.innerHTML = `
    <form method="dialog">
      <p><label>longest side <input id="export-size" type="number" min="1" max="10000" step="1" value="${DEFAULT_PRINT_MM}"> mm</label></p>
      <div class="actions" id="export-formats"></div>
      <p><progress id="export-progress" hidden></progress> <span id="export-status" role="status"></span></p>
      <p><label>Import a penmesh GLB <input id="import-file" type="file" accept=".glb,model/gltf-binary"></label></p>
      <div class="actions"><button id="export-close" value="close">Close</button></div>
    </form>`;
  document.body.append(dialog);
  const $ = (id) => dialog.querySelector(`#${id}`);
  const sizeMm = () => Number($("export-size").value) || DEFAULT_PRINT_MM;
  $("export-size").oninput = () => printSize(sizeMm());
  const progress = $("export-progress");
  const status = $("export-status");
  let busy = false;

  const show = (text, value, max) => {
    status.textContent = text;
    progress.hidden = value === undefined;
    if (max) {
      progress.max = max;
      progress.value = value;
    } else {
      progress.removeAttribute("value"); // indeterminate while the proxy works
    }
  };

  /// Fetches the model, reporting progress; resolves to a Blob. Asked with
  /// `Accept: application/x-ndjson`, the proxy tells each stage's steps line by line, then sends
  /// the file, base64, in the last line (docs/protocol.md).
  async function exportModel(format, sizeMm) {
    const started = performance.now();
    const seconds = () => ((performance.now() - started) / 1000).toFixed(1);
    const label = format.toUpperCase();
    show(`the proxy is making the ${label}…`, 0);
    const res = await fetch(`/v1/sessions/${session}/export?format=${format}&size_mm=${sizeMm}`, {
      headers: { authorization: `Bearer ${token}`, accept: "application/x-ndjson" },
    });
    if (!res.ok) {
      let detail = "";
      try {
        detail = (await res.json()).message;
      } catch {}
      throw new Error(`HTTP ${res.status} ${detail}`);
    }
    const reader = res.body.pipeThrough(new TextDecoderStream()).getReader();
    let pending = "";
    for (;;) {
      const { done, value } = await reader.read();
      if (done) throw new Error("the export was cut off before its file came");
      pending += value;
      let end;
      while ((end = pending.indexOf("\n")) >= 0) {
        const line = JSON.parse(pending.slice(0, end));
        pending = pending.slice(end + 1);
        if (line.progress) {
          const { stage, done: k, total } = line.progress;
          show(`${label}: ${stage} ${k} of ${total}… ${seconds()} s`, k, total);
        } else if (line.error) {
          throw new Error(`HTTP ${line.error.status} ${line.error.message}`);
        } else if (line.file) {
          const bytes = Uint8Array.from(atob(line.file.base64), (c) => c.charCodeAt(0));
          if (bytes.length !== line.file.bytes) throw new Error(`the export was cut off: ${bytes.length} of ${line.file.bytes} bytes`);
          show(`${label} ready: ${(bytes.length / 1024).toFixed(0)} KB in ${seconds()} s`);
          return new Blob([bytes], { type: line.file.content_type });
        }
      }
    }
  }

  async function download(format) {
    if (busy) return;
    busy = true;
    try {
      const blob = await exportModel(format, sizeMm());
      const a = document.createElement("a");
      a.href = URL.createObjectURL(blob);
      a.download = `penmesh-${session}.${format}`;
      a.click();
      setTimeout(() => URL.revokeObjectURL(a.href), 10000);
      // The download has started: the menu gets out of the board's way.
      dialog.close();
      notice(`${format.toUpperCase()} downloaded: penmesh-${session}.${format}`);
    } catch (err) {
      show("");
      fail(`cannot export: ${err.message}`);
    } finally {
      busy = false;
    }
  }

  /// Sends a GLB to the proxy's import; resolves to the strokes it re-created.
  async function importFile(file) {
    show(`importing ${file.name}…`, 0);
    const res = await fetch(`/v1/sessions/${session}/import?name=${encodeURIComponent(name())}`, {
      method: "POST",
      headers: { authorization: `Bearer ${token}`, "x-penmesh-key": key(), "content-type": "model/gltf-binary" },
      body: file,
    });
    const body = await res.json().catch(() => ({}));
    if (!res.ok) {
      show("");
      throw new Error(`${file.name}: ${body.message || `HTTP ${res.status}`}`);
    }
    show(`imported ${body.strokes.length} strokes from ${file.name}`);
    notice(`imported ${body.strokes.length} strokes from ${file.name}`);
    imported(body.strokes.map((s) => s.stroke));
    return body.strokes;
  }

  const importChosen = (file) => importFile(file).catch((err) => fail(`cannot import: ${err.message}`));

  for (const [format, label, title] of FORMATS) {
    const b = document.createElement("button");
    b.type = "button";
    b.id = `export-${format}`;
    b.textContent = label;
    b.title = title;
    b.onclick = () => download(format);
    $("export-formats").append(b);
  }
  $("import-file").onchange = (e) => {
    const file = e.target.files[0];
    if (file && !file.name.toLowerCase().endsWith(".glb")) fail(`cannot import ${file.name}: the page brings back only a GLB scene exported by penmesh (.glb), not ${describe(file.name)}`);
    else if (file) importChosen(file);
    e.target.value = "";
  };
  button.textContent = "Export";
  button.title = "take the model out (GLB, STL, 3MF), or bring a GLB back";
  button.onclick = () => dialog.showModal();
  // A GLB dropped anywhere on the page is imported.
  document.addEventListener("dragover", (e) => {
    if ([...(e.dataTransfer?.items || [])].some((i) => i.kind === "file")) e.preventDefault();
  });
  // Anything else dropped is said so, naming it (the page brings back only GLB scenes).
  document.addEventListener("drop", (e) => {
    const files = [...(e.dataTransfer?.files || [])];
    if (!files.length) return;
    e.preventDefault();
    const file = files.find((f) => f.name.toLowerCase().endsWith(".glb"));
    if (file) return importChosen(file);
    fail(`cannot import ${files.map((f) => f.name).join(", ")}: the page brings back only a GLB scene exported by penmesh (.glb), not ${describe(files[0].name)}`);
  });
  return { exportModel, importFile };
}

/// What a file that is not a GLB is, by its name, for the message that refuses it.
function describe(name) {
  const ext = name.includes(".") ? name.split(".").pop().toLowerCase() : "";
  if (ext === "stl" || ext === "3mf") return `a print (${ext.toUpperCase()}: a closed solid has no strokes to bring back)`;
  return ext ? `a .${ext} file` : "a file without an extension";
}
