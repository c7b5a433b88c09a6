// Page helpers of tests/test_lab.py: run inside JupyterLab (window.jupyterapp, exposed by the
// test's server); each returns what the test asserts on. Several notebooks may be open at once,
// each with its kernel (the next lesson runs while this one is checked); every helper but open
// acts on the current one, chosen with show(path).
window.labTest = (() => {
  const sleep = ms => new Promise(r => setTimeout(r, ms));
  const docs = new Map();     // path -> {panel, seen: kernel statuses, executed, errored}
  let panel = null, doc = null;
  const kernel = () => panel.sessionContext.session?.kernel;
  const idle = () => kernel()?.status === 'idle';
  // wait for cond(); fails after `seconds` without progress: progress() (a count of finished
  // work, e.g. executed cells) restarts the clock whenever it changes
  async function until(cond, what, seconds, progress = () => 0) {
    let end = Date.now() + seconds * 1000, last = progress();
    while (!cond()) {
      const now = progress();
      if (now !== last) { last = now; end = Date.now() + seconds * 1000; }
      if (Date.now() > end) throw new Error(`timed out: ${what} (${seconds} s without progress)`);
      await sleep(100);
    }
  }
  const cellOf = node => panel.content.widgets.findIndex(w => w.node.contains(node));
  function leftoverTeX(root) {
    const bits = [];
    root.querySelectorAll('.jp-RenderedMarkdown, .jp-RenderedLatex').forEach(n => {
      const c = n.cloneNode(true);
      c.querySelectorAll('pre, code, mjx-container, mjx-assistive-mml').forEach(x => x.remove());
      const m = c.textContent.match(/\$\$[^$]+\$\$|\$[^$\s][^$\n]*?\$/g);
      if (m) bits.push(m[0].slice(0, 60));
    });
    return bits;
  }
  const isAnimated = src => /^data:image\/(gif|webp)/.test(src)
    || (src.startsWith('data:image/png') && atob(src.slice(22, 22 + 4000)).includes('acTL'));
  const frame = () => new Promise(r => requestAnimationFrame(r));
  async function visit(i) {
    // scroll the cell into view, as a reader does: JupyterLab renders cells (and typesets their
    // formulas) as they come near the viewport
    await panel.content.scrollToItem(i, 'center').catch(() => null);
    const cell = panel.content.widgets[i];
    await cell.ready; await frame();
    return cell.node;
  }
  async function look(i, found) {
    const node = await visit(i);
    await until(() => leftoverTeX(node).length === 0, 'MathJax to typeset', 20).catch(() => null);
    leftoverTeX(node).forEach(t => found.leftoverTeX.push([i, t]));
    const errors = new Set([...node.querySelectorAll('mjx-merror, .MathJax_Error')].map(e =>
      e.getAttribute('data-mjx-error') || e.textContent.slice(0, 80)));
    errors.forEach(e => found.mathErrors.push([i, e]));
    for (const img of node.querySelectorAll('.jp-Cell-outputArea img')) {
      await img.decode().catch(() => null);
      found.images.push({cell: i, animation: !!img.closest('.animation') || isAnimated(img.src),
                         shown: img.naturalWidth > 0 && img.offsetWidth > 0,
                         naturalWidth: img.naturalWidth, offsetWidth: img.offsetWidth});
    }
    const code = panel.content.widgets[i].model.type === 'code';
    if (code && panel.content.widgets[i].model.outputs.toJSON().some(o =>
        (o.data || {})['application/vnd.jupyter.widget-view+json'])) {
      found.widgetCells.push(i);
      if (!node.querySelector('.jupyter-widgets:not(.jupyter-widgets-error)')
          || /Error displaying widget|Loading widget/.test(node.textContent)) found.deadWidgets.push(i);
    }
  }
  async function report() {
    const cells = panel.content.widgets, outputs = [];
    cells.forEach((c, i) => { if (c.model.type === 'code') {
      c.model.outputs.toJSON().forEach(o => outputs.push([i, c.model.getMetadata('tags') || [], o])); } });
    const text = o => [].concat(o.text || (o.data || {})['text/plain'] || []).join('');
    const found = {dirty: panel.context.model.dirty, mathErrors: [], leftoverTeX: [], images: [],
                   widgetCells: [], deadWidgets: []};
    for (let i = 0; i < cells.length; i++) await look(i, found);
    const failed = o => o.output_type === 'error' || (o.output_type === 'stream' && o.name === 'stderr');
    found.errors = outputs.filter(([, tags, o]) => !tags.includes('raises-exception') && failed(o)).map(
      ([i, , o]) => [i, o.ename ? `${o.ename}: ${o.evalue}`.slice(0, 200) : o.text.slice(0, 200)]);
    found.raw = outputs.filter(([, , o]) => o.output_type !== 'stream' && RAW.test(text(o))).map(([i, , o]) =>
        [i, text(o).slice(0, 80)]);
    return found;
  }
  const RAW = /^<(function|bound method)|object at 0x|np\.(float|int)\d+\(/m;
  async function open(path) {
    await jupyterapp.restored;
    panel = await jupyterapp.commands.execute('docmanager:open', {path});
    doc = {panel, seen: [], executed: 0, errored: 0};
    docs.set(path, doc);
    await panel.context.ready; await panel.sessionContext.ready; await panel.revealed;
    await until(() => kernel() && idle(), 'the kernel to start', 120);
    await kernel().info; await kernel().spec; await sleep(0);   // JupyterLab updates the metadata
    return report();
  }
  function restartRunAll() {     // on the notebook opened last (the active one)
    const d = doc;
    panel.sessionContext.statusChanged.connect((_, s) => { d.seen.push(s); });
    panel.sessionContext.iopubMessage.connect((_, m) => {
      if (m.header.msg_type === 'execute_input') d.executed += 1;
      if (m.header.msg_type === 'error') d.errored += 1; });
    jupyterapp.commands.execute('notebook:restart-run-all');
    return true;
  }
  async function show(path) {   // make an open notebook the current one, on screen
    doc = docs.get(path); panel = doc.panel;
    jupyterapp.shell.activateById(panel.id);
    await panel.revealed; await frame();
    return true;
  }
  async function waitRun(seconds) {     // seconds: one cell's budget (the clock restarts per cell)
    const code = panel.content.widgets.filter(c => c.model.type === 'code'
                                              && c.model.sharedModel.getSource().trim());
    const queued = () => code.some(c => c.model.executionState === 'running');
    const d = doc, finished = () => d.executed >= code.length || d.errored > 0;   // Run All stops at an error
    const done = () => code.filter(c => c.model.executionState !== 'running' && c.model.executionCount).length;
    await until(() => d.seen.includes('restarting') && idle() && !queued() && finished(),
                'Restart Kernel and Run All Cells', seconds, () => `${d.executed}/${done()}/${d.seen.length}`);
    return report();
  }
  async function interacts() {
    const boxes = [];
    for (let i = 0; i < panel.content.widgets.length; i++) {
      if (!panel.content.widgets[i].node.querySelector('.widget-interact')) {
        if (!panel.content.widgets[i].model.outputs?.toJSON().some(o =>
            (o.data || {})['application/vnd.jupyter.widget-view+json'])) continue;
        await visit(i);
      }
      boxes.push(...panel.content.widgets[i].node.querySelectorAll('.widget-interact'));
    }
    return boxes;
  }
  function watch(box) {
    const out = box.querySelector('.widget-output');
    window.__changes = 0;
    if (window.__observer) window.__observer.disconnect();
    window.__observer = new MutationObserver(m => { window.__changes += m.length; });
    window.__observer.observe(out, {childList: true, subtree: true, characterData: true});
  }
  async function redrawn(box, seconds) {
    await until(() => window.__changes > 0 && idle(), 'the widget to redraw', seconds, () => window.__changes);
    const out = box.querySelector('.widget-output');
    const shown = [...out.querySelectorAll('.jp-OutputArea-output')];
    return {
      errors: shown.filter(o => /stderr|error/.test(o.dataset.mimeType || ''))
        .map(o => o.textContent.slice(-300)),
      raw: shown.filter(o => o.dataset.mimeType === 'text/plain').map(o => o.textContent.slice(0, 80)),
      empty: shown.length === 0,
    };
  }
  async function close(path) {    // the current notebook, or the one at path
    const d = path === undefined ? doc : docs.get(path);
    if (!d) return true;
    docs.delete([...docs].find(([, v]) => v === d)[0]);
    await d.panel.sessionContext.shutdown().catch(() => null);
    d.panel.dispose();
    if (d === doc) { doc = null; panel = null; }
    return true;
  }
  return {open, report, restartRunAll, show, waitRun, interacts, watch, redrawn, close};
})();
