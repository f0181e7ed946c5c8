// mapkit open: the page. Leaflet draws; every change is an edit-script operation sent to
// POST /api/edit, applied by mapkit's library on the server. Coordinates are millimetres:
// Leaflet's L.CRS.Simple with lat = y, lng = x (zoom z: 2^z pixels per mm).
'use strict';

const TOKEN = new URLSearchParams(location.search).get('token') || '';
const $ = (id) => document.getElementById(id);
const q = (path) => `${path}?token=${encodeURIComponent(TOKEN)}`;

async function api(method, path, body) {
  const r = await fetch(q(path), {
    method,
    headers: body ? { 'Content-Type': 'application/json' } : {},
    body: body ? JSON.stringify(body) : undefined,
  });
  const doc = await r.json();
  if (!r.ok) throw Object.assign(new Error(doc.error || r.statusText), { status: r.status });
  return doc;
}

// -- state ------------------------------------------------------------------------------------
const state = { doc: null, tool: 'select', selected: null, findings: [] };
const ll = (x, y) => L.latLng(y, x);
const xy = (latlng) => [Math.round(latlng.lng), Math.round(latlng.lat)];
const norm = (a) => { a = ((a + 180) % 360 + 360) % 360 - 180; return a === -180 ? 180 : a; };
const deg = (dx, dy) => Math.atan2(dy, dx) * 180 / Math.PI;

const map = L.map('map', {
  crs: L.CRS.Simple, minZoom: -14, maxZoom: 5, zoomSnap: 1, doubleClickZoom: false,
  boxZoom: false, attributionControl: false,
});
const tiles = L.tileLayer(q('tiles/{v}/{z}/{x}/{y}.png'), {
  v: -1, minZoom: -14, maxZoom: 5, maxNativeZoom: 3, noWrap: true, keepBuffer: 4,
});
const objectLayer = L.layerGroup().addTo(map);
const handleLayer = L.layerGroup().addTo(map);
const findingLayer = L.layerGroup().addTo(map);
const draftLayer = L.layerGroup().addTo(map);
window.mapkit = { map, state, tiles, firstPaint: null };
tiles.on('load', () => { if (window.mapkit.firstPaint === null) window.mapkit.firstPaint = performance.now(); });

// Names and messages come from the file: always put them in the page as text, never as HTML.
function textNode(s) {
  const span = document.createElement('span');
  span.textContent = s;
  return span;
}
const esc = (s) => s.replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);

function status(text, error) {
  $('status').textContent = text;
  $('status').className = error ? 'error' : '';
}

// -- drawing the map --------------------------------------------------------------------------
const BADGE = { Goal: ['G', '#2a7'], Dock: ['D', '#27a'], RobotHome: ['H', '#a72'] };

function pointIcon(o, selected) {
  const [letter, colour] = BADGE[o.base_type] || BADGE[o.type.replace('WithHeading', '')] || [o.type[0].replace(/[^A-Za-z0-9]/, '?'), '#666'];
  const arrow = o.type.endsWith('WithHeading') || o.type === 'Dock' || o.type === 'RobotHome' || o.theta
    ? `<div class="arrow" style="transform: rotate(${-o.theta}deg)"></div>` : '';
  return L.divIcon({
    className: 'obj' + (selected ? ' sel' : ''), iconSize: [22, 22], iconAnchor: [11, 11],
    html: `${arrow}<div class="badge" style="background:${colour}">${letter}</div>${label(o)}`,
  });
}

// Names are part of the markers' HTML, not Leaflet tooltips: hundreds of permanent tooltips
// each measure themselves on every zoom, which made zooming a big map crawl.
const label = (o) => (o.name ? `<span class="name">${esc(o.name)}</span>` : '');
const labelIcon = (o) => L.divIcon({ className: 'obj-label', iconSize: [0, 0], html: label(o) });

function objectShape(o, selected) {
  const forbidden = o.type.startsWith('Forbidden');
  const style = { color: selected ? '#fb0' : (forbidden ? '#c22' : '#37a'), weight: selected ? 3 : 2 };
  let layer;
  if (o.shape === 'rect') {
    layer = L.polygon(o.corners.map(([x, y]) => ll(x, y)),
      { ...style, fillColor: forbidden ? 'url(#hatch)' : '#37a', fillOpacity: forbidden ? 1 : 0.15 });
  } else if (o.shape === 'line') {
    layer = L.polyline(o.corners.map(([x, y]) => ll(x, y)), { ...style, dashArray: forbidden ? '6 4' : null });
  } else {
    layer = L.marker(ll(o.x, o.y), { icon: pointIcon(o, selected), keyboard: false });
  }
  layer.on('click', (e) => { if (state.tool === 'select') { L.DomEvent.stop(e); select(o.index); } });
  if (o.shape === 'point' || !o.name) return layer;
  return L.layerGroup([layer, L.marker(ll(...o.centre), { icon: labelIcon(o), interactive: false, keyboard: false })]);
}

function render(doc) {
  state.doc = doc;
  $('file').textContent = doc.file.split('/').pop();
  $('dirty').hidden = !doc.dirty;
  $('undo').disabled = !doc.can_undo;
  $('redo').disabled = !doc.can_redo;
  if (tiles.options.v !== doc.data_version) {
    const [[x0, y0], [x1, y1]] = doc.bounds;  // ask only for tiles where there is something
    tiles.options.bounds = L.latLngBounds(ll(x0, y0), ll(x1, y1)).pad(0.05);
    tiles.options.v = doc.data_version;
    tiles.redraw();
  }
  objectLayer.clearLayers();
  for (const o of doc.objects) objectLayer.addLayer(objectShape(o, o.index === state.selected));
  if (state.selected && !doc.objects.some((o) => o.index === state.selected)) state.selected = null;
  renderList();
  renderSelection();
  renderTypes(doc.types);
  showNames();
  for (const b of document.querySelectorAll('#tools button')) {
    b.hidden = doc.kind === 'ros' && !['select', 'area', 'fline'].includes(b.dataset.tool);
  }
}

function renderList() {
  const needle = $('search').value.trim().toLowerCase();
  const ul = $('objects');
  ul.textContent = '';
  for (const o of state.doc.objects) {
    const text = `#${o.index} ${o.type} ${o.name}`;
    if (needle && !text.toLowerCase().includes(needle)) continue;
    const li = document.createElement('li');
    li.textContent = text;
    li.className = o.index === state.selected ? 'sel' : '';
    li.onclick = () => { select(o.index); map.panTo(ll(...o.centre)); };
    ul.appendChild(li);
  }
}

function renderTypes(types) {
  const sel = $('type');
  if (sel.options.length === types.length) return;
  sel.textContent = '';
  for (const t of types) sel.add(new Option(`${t.name} (${t.shape || 'point or area'})`, t.name));
  sel.onchange = renderParams;
  renderParams();
}

function renderParams() {
  const t = (state.doc.types || []).find((x) => x.name === $('type').value);
  const box = $('params');
  box.textContent = '';
  for (const p of (t ? t.params : [])) {
    const label = document.createElement('label');
    label.textContent = `${p.name} `;
    const input = document.createElement('input');
    input.dataset.param = p.name;
    input.placeholder = p.default;
    label.appendChild(input);
    box.appendChild(label);
    box.appendChild(document.createElement('br'));
  }
}

// -- selection and its handles ----------------------------------------------------------------
const selectedObject = () => state.doc && state.doc.objects.find((o) => o.index === state.selected);
const pxToMm = (px) => px / Math.pow(2, map.getZoom());

function select(index) {
  state.selected = index;
  render(state.doc);
}

function handle(latlng, cls, onDrop) {
  const m = L.marker(latlng, {
    draggable: true, keyboard: false, zIndexOffset: 1000,
    icon: L.divIcon({ className: `handle ${cls}`, iconSize: [12, 12], iconAnchor: [6, 6] }),
  });
  m.on('dragend', () => onDrop(m.getLatLng()));
  return m;
}

function renderSelection() {
  handleLayer.clearLayers();
  const o = selectedObject();
  $('selection').hidden = !o;
  if (!o) return;
  $('sel-title').textContent = `#${o.index} ${o.type}`;
  $('sel-name').value = o.name;
  $('sel-heading').value = o.shape === 'line' ? '' : Math.round(o.theta * 100) / 100;
  $('sel-heading').disabled = $('sel-turn').disabled = o.shape === 'line';
  const [cx, cy] = o.centre;
  const sel = `#${o.index}`;
  handleLayer.addLayer(handle(ll(cx, cy), 'move', (p) => {
    const [x, y] = xy(p);
    edit({ move: { name: sel, x, y } });
  }));
  if (o.shape === 'line') return;
  // The rotation handle: along the heading for a point, beyond the "top" edge for a rectangle.
  let dir = o.theta, reach = pxToMm(45);
  if (o.shape === 'rect') {
    const [, b, c] = o.corners;
    reach += Math.hypot(c[0] - b[0], c[1] - b[1]) / 2;
    dir = o.theta + 90;
  }
  const r = dir * Math.PI / 180;
  handleLayer.addLayer(handle(ll(cx + reach * Math.cos(r), cy + reach * Math.sin(r)), 'rotate', (p) => {
    const a = deg(p.lng - cx, p.lat - cy) - (o.shape === 'rect' ? 90 : 0);
    edit({ move: { name: sel, heading: norm(Math.round(a)) } });
  }));
}

// -- talking to the server --------------------------------------------------------------------
async function send(method, path, body, then) {
  try {
    const out = await api(method, path, body);
    render(out.map || out);
    status((out.summary || [out.message || '']).join('; '));
    $('reload').hidden = true;
    if (then) then(out);
    return out;
  } catch (err) {
    status(err.message, true);
    if (err.status === 409) $('reload').hidden = false;
    return null;
  }
}

const edit = (...edits) => send('POST', 'api/edit', { edits });
// Read the map again (after a script changed it through the API).
window.mapkit.refresh = () => send('GET', 'api/map');
const selectNewest = () => select(state.doc.objects.length);

function freeName(base) {
  const names = new Set(state.doc.objects.map((o) => o.name.toLowerCase()));
  for (let i = 1; ; i++) if (!names.has(`${base}${i}`.toLowerCase())) return `${base}${i}`;
}

// -- tools ------------------------------------------------------------------------------------
// A drag gives (a, b) in mm; a click gives a === b. Each tool turns that into one edit.
function heading(a, b, p0, p1) {
  return p0.distanceTo(p1) >= 6 ? norm(Math.round(deg(b[0] - a[0], b[1] - a[1]))) : undefined;
}

function params() {
  const out = {};
  for (const i of document.querySelectorAll('#params input')) if (i.value !== '') out[i.dataset.param] = i.value;
  return out;
}

const TOOLS = {
  goal: (a, b, h) => edit({ 'add-goal': { name: freeName('Goal'), x: a[0], y: a[1], heading: h } }),
  dock: (a, b, h) => edit({ 'add-dock': { name: freeName('Dock'), x: a[0], y: a[1], heading: h ?? 0 } }),
  home: (a, b, h) => edit({ 'add-home': { x: a[0], y: a[1], heading: h ?? 0 } }),
  area: (a, b) => box(a, b) && send('POST', 'api/edit', { edits: [{ forbid: { area: [...a, ...b] } }] }, selectNewest),
  fline: (a, b) => box(a, b) && edit({ forbid: { line: [...a, ...b] } }),
  erasebox: (a, b) => box(a, b) && edit({ erase: { box: [...a, ...b] } }),
  wall: (a, b) => box(a, b) && edit({ 'draw-line': { line: [...a, ...b] } }),
  object: (a, b, h) => {
    const t = (state.doc.types || []).find((x) => x.name === $('type').value);
    if (!t) return status('this map declares no types', true);
    const spec = { type: t.name, name: freeName(t.name), params: params() };
    const dragged = a[0] !== b[0] || a[1] !== b[1];
    if (t.shape === 'line') spec.line = [...a, ...b];
    else if (t.shape === 'rect' || (t.shape === null && dragged)) spec.area = [...a, ...b];
    else { spec.at = a; if (h !== undefined) spec.heading = h; }
    return edit({ 'add-object': spec });
  },
};
const DRAGS_BOX = new Set(['area', 'erasebox', 'object']);
const box = (a, b) => (a[0] !== b[0] || a[1] !== b[1]) || (status('drag to draw it', true), false);

function setTool(name) {
  state.tool = name;
  cancelDraft();
  for (const b of document.querySelectorAll('#tools button')) b.classList.toggle('on', b.dataset.tool === name);
  $('typebox').hidden = name !== 'object';
  $('map').classList.toggle('drawing', name !== 'select');
  if (name === 'select') map.dragging.enable(); else map.dragging.disable();
}

let drag = null;       // {a, p0, layer} while a tool's drag is under way
let polygon = null;    // vertices of an erase polygon being drawn
function cancelDraft() { drag = null; polygon = null; draftLayer.clearLayers(); }

map.on('mousedown', (e) => {
  if (state.tool === 'select' || state.tool === 'erasepoly' || e.originalEvent.button !== 0) return;
  drag = { a: xy(e.latlng), p0: e.containerPoint, layer: null };
});
map.on('mousemove', (e) => {
  $('coords').textContent = `x ${Math.round(e.latlng.lng)}  y ${Math.round(e.latlng.lat)} mm`;
  if (!drag) return;
  const b = xy(e.latlng);
  draftLayer.clearLayers();
  const A = ll(...drag.a), B = ll(...b);
  draftLayer.addLayer(DRAGS_BOX.has(state.tool) ? L.rectangle([A, B], { color: '#f80', weight: 1, interactive: false })
    : L.polyline([A, B], { color: '#f80', weight: 2, interactive: false }));
});
map.on('mouseup', (e) => {
  if (!drag) return;
  const { a, p0 } = drag;
  const b = xy(e.latlng);
  cancelDraft();
  TOOLS[state.tool](a, b, heading(a, b, p0, e.containerPoint));
});
// An erase polygon: click the corners; finish with a click on the first corner, a double-click
// or Enter.
function finishPolygon() {
  if (state.tool !== 'erasepoly' || !polygon) return;
  const pts = polygon.filter((p, i) => i === 0 || p[0] !== polygon[i - 1][0] || p[1] !== polygon[i - 1][1]);
  cancelDraft();
  if (pts.length < 3) return status('an erase polygon needs 3 corners or more', true);
  edit({ erase: { polygon: pts } });
}
map.on('click', (e) => {
  if (state.tool === 'select') { state.selected = null; render(state.doc); return; }
  if (state.tool !== 'erasepoly') return;
  polygon = polygon || [];
  if (polygon.length >= 3 && map.latLngToContainerPoint(ll(...polygon[0])).distanceTo(e.containerPoint) < 8) {
    return finishPolygon();
  }
  polygon.push(xy(e.latlng));
  draftLayer.clearLayers();
  draftLayer.addLayer(L.polyline(polygon.map((p) => ll(...p)), { color: '#f80', weight: 2, interactive: false }));
});
map.on('dblclick', finishPolygon);

// -- controls: scale bar and cursor coordinates -----------------------------------------------
const Scale = L.Control.extend({
  onAdd() {
    const div = L.DomUtil.create('div', 'scalebar');
    const update = () => {
      const mmPerPx = pxToMm(1);
      const target = 100 * mmPerPx;
      const p = Math.pow(10, Math.floor(Math.log10(target)));
      const len = [5, 2, 1].map((k) => k * p).find((v) => v <= target) || p;
      div.style.width = `${Math.round(len / mmPerPx)}px`;
      div.textContent = len >= 1000 ? `${len / 1000} m` : `${len} mm`;
    };
    map.on('zoomend', update);
    update();
    return div;
  },
});
new Scale({ position: 'bottomleft' }).addTo(map);
// Names only where they can be read: zoomed in (<= 64 mm per pixel) or on maps with few objects.
const showNames = () => map.getContainer().classList.toggle('no-names',
  map.getZoom() < -6 && !!state.doc && state.doc.objects.length > 30);
map.on('zoomend', showNames);
const Coords = L.Control.extend({ onAdd: () => Object.assign(L.DomUtil.create('div', 'coords'), { id: 'coords' }) });
new Coords({ position: 'bottomright' }).addTo(map);

// -- findings ---------------------------------------------------------------------------------
async function validate() {
  status('validating...');
  try {
    state.findings = (await api('GET', 'api/validate')).findings;
  } catch (err) {
    return status(err.message, true);
  }
  findingLayer.clearLayers();
  const ul = $('findings');
  ul.textContent = '';
  for (const f of state.findings) {
    const li = document.createElement('li');
    li.className = f.severity;
    li.textContent = `MK${f.code} ${f.message}`;
    ul.appendChild(li);
    if (!f.xy) continue;
    const colour = { error: '#c00', warning: '#d80', info: '#48a' }[f.severity];
    findingLayer.addLayer(L.circleMarker(ll(...f.xy), { radius: 8, color: colour, weight: 2, fill: false })
      .bindTooltip(textNode(`MK${f.code}`), { permanent: true, direction: 'top', className: 'code' })
      .bindPopup(textNode(`MK${f.code} ${f.name}: ${f.message}`)));
    li.onclick = () => map.panTo(ll(...f.xy));
  }
  const n = state.findings.length;
  $('fcount').textContent = `${n} finding${n === 1 ? '' : 's'}`;
  status('');
}

// -- buttons and keys -------------------------------------------------------------------------
for (const b of document.querySelectorAll('#tools button')) b.onclick = () => setTool(b.dataset.tool);
$('undo').onclick = () => send('POST', 'api/undo');
$('redo').onclick = () => send('POST', 'api/redo');
$('save').onclick = () => send('POST', 'api/save', { backup: $('backup').checked });
$('reload').onclick = () => send('POST', 'api/reload');
$('validate').onclick = validate;
$('search').oninput = renderList;
$('sel-rename').onclick = () => edit({ rename: { name: `#${state.selected}`, 'new-name': $('sel-name').value } });
$('sel-turn').onclick = () => edit({ move: { name: `#${state.selected}`, heading: Number($('sel-heading').value) } });
$('sel-delete').onclick = () => { const i = state.selected; state.selected = null; edit({ remove: { names: [`#${i}`] } }); };
document.addEventListener('keydown', (e) => {
  if (e.target.tagName === 'INPUT') return;
  const k = e.key.toLowerCase();
  if ((e.ctrlKey || e.metaKey) && k === 'z') { e.preventDefault(); send('POST', e.shiftKey ? 'api/redo' : 'api/undo'); }
  else if ((e.ctrlKey || e.metaKey) && k === 'y') { e.preventDefault(); send('POST', 'api/redo'); }
  else if ((e.ctrlKey || e.metaKey) && k === 's') { e.preventDefault(); $('save').click(); }
  else if (k === 'escape') setTool('select');
  else if (k === 'enter') finishPolygon();
  else if (k === 'delete' && state.selected) $('sel-delete').click();
});

// -- start ------------------------------------------------------------------------------------
api('GET', 'api/map').then((doc) => {
  const [[x0, y0], [x1, y1]] = doc.bounds;
  map.fitBounds(L.latLngBounds(ll(x0, y0), ll(x1, y1)), { padding: [20, 20], animate: false });
  render(doc);
  tiles.addTo(map);
  setTool('select');
  status(`${doc.counts.points} points, ${doc.counts.lines} lines, ${doc.counts.objects} objects`);
  window.mapkit.ready = true;
}).catch((err) => status(err.message, true));
