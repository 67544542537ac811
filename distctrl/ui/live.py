"""The live page's changing texts, without re-drawing the page (issue 24).

A Bokeh ``Div`` whose text changes is rendered anew and makes the browser lay out the whole page
again: every tab, the object browser's table, every plot. At 20 changes a second that took the
browser's main thread whole (the PLC panel fell 40 s behind, its buttons were never still long enough
to be clicked). So the texts that change while the page is open (the clock, the status line, the PLC
panel's control units, the machine view's and the object browser's read-outs, the messages) are
written once as a fixed HTML skeleton whose ``<span data-k="KEY">`` elements are filled by a small
script of the page (:data:`PAGE_JS`): the server sends only the keys whose text changed, as one
property of one data model (:class:`LiveValues`, no view, no layout), and the script sets those
elements' ``textContent``. Nothing else on the page moves.

Flow control: every such message carries a frame number (``__seq``) and the server's wall clock
(``__sent``); the page answers with the last frame number it has drawn (``ack``, set in the
browser's next animation frame after the message). A page more than :data:`MAX_IN_FLIGHT` frames
behind gets no new frame until it catches up (the scope then streams the rows it missed in one go):
a slow browser gets fewer frames instead of a growing queue.

The script also tells the user when the page is behind (the last message arrived more than
:data:`BEHIND_S` later than the fastest one did) or the connection has stalled (no message for
:data:`STALL_S`), in the status line.
"""
from __future__ import annotations

import html
import time

import json

from bokeh.core.properties import Int, String
from bokeh.model import DataModel

#: frames the server sends ahead of the last one the page has acknowledged; a change of the status
#: line or a message (the answer to a click) may go this many more (they are small and should show at
#: once)
MAX_IN_FLIGHT = 3
URGENT_EXTRA = 2
#: the page acknowledges every ACK_EVERY-th frame it has drawn, or a drawn frame ACK_MS after it has
#: drawn it: each acknowledgement is a message into the page's thread (and Bokeh's answer to it), which
#: beside the 1 ms cycle cost as much as a frame; MAX_IN_FLIGHT leaves room for the frames in between
ACK_EVERY = 2
ACK_MS = 100
#: the page says "behind" from this lateness (s) and "stalled" after this long without a message (s)
BEHIND_S = 1.0
STALL_S = 2.5

#: styles of the live elements, by the state the server gives them (``data-s``); a Div's stylesheet
#: (a string: a stylesheet model would belong to one page's document only)
STYLE = """
[data-s="ok"] { color: green; }
[data-s="err"] { color: #c00; font-weight: bold; }
[data-s="warn"] { color: darkorange; font-weight: bold; }
.pre { white-space: pre-line; }
"""


class LiveValues(DataModel):
    """One page's changing texts: ``values`` is the last delta as JSON text (key -> text, or [text,
    state]), with ``__seq`` (frame number), ``__sent`` (server wall clock, s) and ``__rows`` (the scope's
    new rows); ``ack`` is set by the page.

    Text, not a Bokeh dict: Bokeh walks a changed property's old and new value for models they might
    hold, every element of them, which cost about 1 ms a frame with the scope's rows (issue 39)."""

    values = String("", help="the keys that changed in this frame (JSON)")
    ack = Int(0, help="the last frame number the page has drawn")


def span(key: str, text: str = "", cls: str = "", tag: str = "span") -> str:
    """The HTML of one live element (its initial text; the page script keeps it up to date)."""
    c = f' class="{cls}"' if cls else ""
    return f'<{tag}{c} data-k="{html.escape(key)}">{html.escape(text)}</{tag}>'


class Live:
    """The server side of one page's live values."""

    #: the wall clock the frames are stamped with (s)
    clock = staticmethod(time.time)

    def __init__(self):
        self.model = LiveValues(name="dc-live")
        self.seq = 0
        self.shown: dict[str, object] = {}
        self.staged: dict[str, object] = {}
        self.skipped = 0
        #: the last message sent (what ``values`` holds as JSON text)
        self.last: dict = {}

    @property
    def in_flight(self) -> int:
        """Frames sent that the page has not drawn yet."""
        return self.seq - int(self.model.ack or 0)

    def can_send(self, urgent: bool = False) -> bool:
        ok = self.in_flight < MAX_IN_FLIGHT + (URGENT_EXTRA if urgent else 0)
        if not ok:
            self.skipped += 1
        return ok

    def stage(self, values: dict) -> None:
        """Values to send with the next frame (a message after a click)."""
        self.staged.update(values)

    def push(self, values: dict | None = None, rows: list | None = None) -> None:
        """Send the keys of ``values`` (and the staged ones) whose text changed, with the frame number
        and the time: one message, always (it is also the page's heartbeat). ``rows``: the scope's new
        rows (:meth:`distctrl.ui.scope.Scope.update`), streamed by the page's script into the plot."""
        if values:
            self.staged.update(values)
        delta = {k: v for k, v in self.staged.items() if self.shown.get(k) != v}
        self.staged = {}
        self.shown.update(delta)
        if not self.model.ack:
            # the page has drawn nothing yet: it may have connected after values changed (its document
            # holds only the last message), so it gets them all until it acknowledges a frame
            delta = dict(self.shown)
        self.seq += 1
        delta["__seq"] = self.seq
        delta["__sent"] = round(self.clock(), 3)
        if rows:
            delta["__rows"] = rows
        self.last = delta
        self.model.values = json.dumps(delta, separators=(",", ":"), allow_nan=False)


#: the name of the object browser's table: the page script redraws its grid after a change of its source
TABLE_NAME = "dc-objects"

#: the page's script (in the page template; the Content-Security-Policy allows inline scripts, not
#: eval, so no CustomJS): finds the live model, applies every delta to the elements ``[data-k]``
#: (looked up once through the Bokeh views' shadow roots, again when one has been re-rendered),
#: acknowledges the frame after the browser has drawn it, and shows "behind" / "stalled". It also redraws
#: the object browser's grid when its source changes: Bokeh 3.9's DataTable redraws only when its view's
#: indices change (CDSView sets equal indices silently), so patched values stood still on the page.
PAGE_JS = """
(function () {
  const BEHIND = %(behind)s, STALL = %(stall)s, ACK_EVERY = %(ack_every)s, ACK_MS = %(ack_ms)s;
  let live = null, els = {}, state = {}, lastScan = 0, lastArrival = 0, base = Infinity, behind = 0;
  let lastSeq = 0, ackQueued = false, acked = 0, ackTimer = null;
  const scan = () => {
    const found = {};
    const walk = (root) => {
      for (const e of root.querySelectorAll('[data-k]')) (found[e.dataset.k] = found[e.dataset.k] || []).push(e);
      for (const h of root.querySelectorAll('*')) if (h.shadowRoot) walk(h.shadowRoot);
    };
    walk(document);
    for (const k in found) if (k in state && (!els[k] || els[k].some((e) => !found[k].includes(e)))) {
      for (const e of found[k]) put(e, state[k]);
    }
    els = found;
    lastScan = performance.now();
  };
  const put = (e, v) => {
    const [text, s] = Array.isArray(v) ? v : [v, ''];
    if (e.textContent !== text) e.textContent = text;
    if ((e.dataset.s || '') !== s) e.dataset.s = s;
  };
  const set = (k, v) => {
    state[k] = v;
    let list = els[k];
    if ((!list || list.some((e) => !e.isConnected)) && performance.now() - lastScan > 300) {
      scan(); list = els[k];
    }
    if (list) for (const e of list) put(e, v);
  };
  const sendAck = () => {
    if (ackTimer !== null) clearTimeout(ackTimer);
    ackTimer = null;
    if (live && acked !== lastSeq) { acked = lastSeq; live.ack = lastSeq; }
  };
  const ack = () => {                  // after the browser has drawn the frames up to lastSeq
    ackQueued = false;
    if (lastSeq - acked >= ACK_EVERY) sendAck();
    else if (ackTimer === null && acked !== lastSeq) ackTimer = setTimeout(sendAck, ACK_MS);
  };
  const apply = () => {
    if (!live.values) return;
    const d = JSON.parse(live.values);
    if (d.__seq === undefined) return;
    const now = Date.now() / 1000, off = now - d.__sent;
    if (off < base || off - base > 600) base = off;
    behind = off - base;
    lastArrival = now;
    lastSeq = d.__seq;
    for (const k in d) if (!k.startsWith('__')) set(k, d[k]);
    // the scope's new rows, into its sources here (sync false: the server keeps its ring buffer)
    if (d.__rows && live.document) for (const [id, data, n] of d.__rows) {
      const src = live.document.get_model_by_id(id);
      if (!src) continue;
      for (const c in data) data[c] = Float64Array.from(data[c], (v) => (v === null ? NaN : v));
      src.stream(data, n, {sync: false});
    }
    if (!ackQueued) {
      ackQueued = true;
      requestAnimationFrame(ack);
      setTimeout(() => { if (ackQueued) ack(); }, 1000);   // a hidden page draws no frames
    }
  };
  const indicator = () => {
    if (!lastArrival) return;
    const silent = Date.now() / 1000 - lastArrival;
    let v = '';
    if (silent > STALL) v = ['connection stalled: no update for ' + silent.toFixed(0) + ' s', 'err'];
    else if (behind > BEHIND) v = ['page behind by ' + behind.toFixed(1) + ' s', 'warn'];
    const old = state.__lag;
    if (JSON.stringify(old || '') !== JSON.stringify(v)) set('__lag', v);
  };
  const find = () => {
    if (!window.Bokeh || !Bokeh.documents || !Bokeh.documents.length) return setTimeout(find, 100);
    for (const doc of Bokeh.documents) { live = doc.get_model_by_name('dc-live'); if (live) break; }
    if (!live) return setTimeout(find, 100);
    scan();
    // the plots' automatic ranges (DataRange1d: the scope's time axis follows the data) stay in the
    // browser: Bokeh would send every change of their start and end to the server, a message into
    // the page's thread for every frame drawn, which the server never reads
    for (const doc of Bokeh.documents) for (const m of doc.all_models) {
      const proto = Object.getPrototypeOf(m);
      if ((m.constructor.__qualified__ || m.constructor.__name__) === 'DataRange1d' && !proto.__dcLocal) {
        const setv = proto.setv;
        proto.setv = function (attrs, options) {
          return setv.call(this, attrs, {...(options || {}), sync: false});
        };
        proto.__dcLocal = true;
      }
    }
    live.properties.values.change.connect(apply);
    apply();
    let table = null;
    for (const doc of Bokeh.documents) { table = doc.get_model_by_name('%(table)s'); if (table) break; }
    if (table) {
      const redraw = () => {
        const walk = (v) => {
          if (v.model === table) { if (v.updateGrid) v.updateGrid(); return; }
          for (const c of (v.child_views || [])) walk(c);
        };
        for (const root of Object.values(Bokeh.index)) walk(root);
      };
      table.source.patching.connect(redraw);
      table.source.properties.data.change.connect(redraw);
    }
    setInterval(indicator, 250);
  };
  find();
})();
""" % {"behind": BEHIND_S, "stall": STALL_S, "table": TABLE_NAME, "ack_every": ACK_EVERY, "ack_ms": ACK_MS}
