"""Executes a parsed NC program against a channel, one GEO cycle at a time.

The interpreter knows nothing of the machine behind the channel; it only uses the small
:class:`Channel` protocol (start a move, start a dwell, send a distance-control command to an axis,
read and write variables). Blocks without motion or dwell complete in the cycle they are read, so a
``Z[DIST_CTRL ON]`` followed by a move reaches the controller in the cycle the move starts.

Runtime problems (an undefined variable, a value out of range once an expression is evaluated)
stop the program with :class:`NcRuntimeError` recorded in :attr:`NcInterpreter.error` — a value,
like every error on the cycle path.

3D distance control and kinematics (FCT-M3 ch. 12, docs/run-3d.md): a ``#DIST CTRL`` block
hands its :class:`~distctrl.control.commands3d.Command3D` to the channel (``dist_ctrl_3d``) and
takes its GEO cycle; with WAIT the next block waits for ``dist_ctrl_3d_done``. A channel without
FCT_3D_DIST_CTRL (``has_dist_ctrl_3d`` false) stops the program with 20209 ("Unknown Nc-command").
``#KIN``/``#TRAFO``/``#CS``/``#CHANNEL INIT`` go to ``channel.kinematics(word, lookup, line)``; a
channel method that refuses a block raises :class:`NcAbort` (e.g. 51062, 900020), which stops the
program with that ID and the block's line. After a block's assignments the channel is told which
variables were written (``variables_assigned``), so it can re-read the tool length and the
kinematic parameters.

Look-ahead (block preparation): a channel with ``look_ahead = N > 0`` gets with each G1 block the
(length, feed) of up to N following blocks that continue it on the same straight line in the same
direction (``start_linear(target, feed, ahead=...)``), so its interpolator need not stop between them
(:mod:`distctrl.sim.interpolator`, "Look-ahead"). Only blocks whose effect is known before they run
are prepared: G1 motion with constant axis values and feed, nothing else in the block (no
assignment, DIST_CTRL, dwell, M function, #WAIT FOR, G0); the first other block ends the chain, and
the last prepared block stops at its end unless it prepares its own followers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from ..control.commands import Action, Command
from ..control.commands3d import Command3D
from ..errors import ErrorId
from .program import ExprError, NcSyntaxError, Program

#: G codes a prepared (look-ahead) block may carry
_CHAIN_G_CODES = frozenset((1, 90, 91))


def _constant(name: str) -> float:
    raise ExprError(f"variable {name} is not known before the block runs")

#: a program that loops through this many blocks without motion in one cycle is stopped
MAX_BLOCKS_PER_CYCLE = 10_000
NC_RUNTIME_ERROR = int(ErrorId.NC_RUNTIME)    # 900010
#: FCT-M3 §12.7 notice: #DIST CTRL without FCT_3D_DIST_CTRL (P-CHAN-00500): "Unknown Nc-command"
UNKNOWN_NC_COMMAND = 20209


class NcAbort(Exception):
    """Raised by a channel method to refuse a block: the program stops with ``id`` and the block's line."""

    def __init__(self, error_id: int, message: str):
        super().__init__(message)
        self.id = int(error_id)
        self.message = message


class Channel(Protocol):
    """What the interpreter needs from the machine."""

    positions: dict[str, float]          # programmed positions (mm), by axis name
    variables: dict[str, float]          # "V.E.NAME" / "V.G.WZ_AKT.L" -> value

    def start_linear(self, target: dict[str, float], feed_mm_min: float | None) -> None: ...

    def start_dwell(self, seconds: float) -> None: ...

    def motion_done(self) -> bool: ...

    def dist_ctrl(self, axis: str, command: Command) -> None: ...

    def dist_ctrl_done(self, axis: str, action: Action) -> bool:
        """WAIT: has the axis's last DIST_CTRL command completed (SPEC §8)?"""
        ...

    # optional (3D distance control and kinematics; see the module docstring):
    # has_dist_ctrl_3d: bool
    # def dist_ctrl_3d(self, command: Command3D) -> None
    # def dist_ctrl_3d_done(self, action: Action) -> bool
    # def kinematics(self, word, lookup, line) -> None
    # def variables_assigned(self, names: list[str]) -> None


@dataclass(frozen=True)
class NcRuntimeError:
    """A program stopped at run time (value, not exception)."""

    id: int
    line: int | None
    message: str


class NcInterpreter:
    """Steps through ``program`` on ``channel``: call :meth:`tick` once per GEO cycle before the
    interpolator runs. Modal state: G0/G1, G90/G91, F."""

    def __init__(self, program: Program, channel: Channel, file: str | None = None):
        self.program = program
        self.channel = channel
        self.file = file or program.source
        self.index = 0                    # next block to read
        self.line: int | None = None      # line of the block being executed
        self.rapid = True                 # G0 until G1 is programmed
        self.absolute = True              # G90
        self.feed: float | None = None    # mm/min
        self.ended = False                # M30/M2 reached or the last block done
        self.aborted = False
        self.error: NcRuntimeError | None = None
        self.end_line: int | None = None
        self._end_pending = False         # M30 in a block with motion: ends when the motion is done
        self._waits: list[tuple[str, Action]] = []   # DIST_CTRL WAIT commands the block waits for
        self._waits_3d: list[Action] = []            # #DIST CTRL WAIT commands the block waits for
        self._wait_for = None                        # the #WAIT FOR condition the program waits on

    @property
    def running(self) -> bool:
        return not (self.ended or self.aborted)

    def abort(self, error: NcRuntimeError | None = None) -> None:
        """Stop reading blocks (an error elsewhere, a reset)."""
        if self.running:
            self.aborted = True
            if error is not None and self.error is None:
                self.error = error

    def tick(self) -> None:
        """Read and start blocks until one takes time (motion, dwell) or the program ends."""
        if not self.running:
            return
        ch = self.channel
        if not ch.motion_done():
            return
        if self._waits:
            if not all(ch.dist_ctrl_done(axis, action) for axis, action in self._waits):
                return
            self._waits = []
        if self._waits_3d:
            if not all(ch.dist_ctrl_3d_done(action) for action in self._waits_3d):
                return
            self._waits_3d = []
        if self._wait_for is not None and not self._condition_holds():
            return
        if self._end_pending:
            self.ended = True
            return
        blocks = self.program.blocks
        for _ in range(MAX_BLOCKS_PER_CYCLE):
            if self.index >= len(blocks):
                self.ended = True          # no M30: the program ends after its last block
                return
            block = blocks[self.index]
            self.index += 1
            self.line = block.line
            try:
                takes_time = self._execute(block)
            except NcAbort as exc:
                self.abort(NcRuntimeError(exc.id, block.line, exc.message))
                return
            except (ExprError, NcSyntaxError, ZeroDivisionError, OverflowError, ValueError) as exc:
                msg = exc.message if isinstance(exc, NcSyntaxError) else str(exc)
                self.abort(NcRuntimeError(NC_RUNTIME_ERROR, block.line, msg))
                return
            if not self.running:
                return
            if takes_time:
                return
        self.abort(NcRuntimeError(NC_RUNTIME_ERROR, self.line,
                                  f"more than {MAX_BLOCKS_PER_CYCLE} blocks without motion in one cycle"))

    def _condition_holds(self) -> bool:
        """``#WAIT FOR``: is the condition fulfilled (> 0.5)? Evaluated every cycle the channel is idle;
        a condition that cannot be evaluated (an undefined variable) stops the program (900010)."""
        try:
            value = self._wait_for.evaluate(self._lookup)
        except (ExprError, ZeroDivisionError, OverflowError, ValueError) as exc:
            self.abort(NcRuntimeError(NC_RUNTIME_ERROR, self.line, f"#WAIT FOR: {exc}"))
            return False
        if value > 0.5:
            self._wait_for = None
            return True
        return False

    # ------------------------------------------------------------------ one block
    def _lookup(self, name: str) -> float:
        try:
            return float(self.channel.variables[name])
        except KeyError:
            raise ExprError(f"variable {name} is not defined") from None

    def _execute(self, block) -> bool:
        ch = self.channel
        lookup = self._lookup
        for a in block.assignments:
            ch.variables[a.var] = a.value.evaluate(lookup)
        if block.assignments:
            hook = getattr(ch, "variables_assigned", None)
            if hook is not None:
                hook([a.var for a in block.assignments])
        for g in block.g_codes:
            if g == 0:
                self.rapid = True
            elif g == 1:
                self.rapid = False
            elif g == 90:
                self.absolute = True
            elif g == 91:
                self.absolute = False
        if block.feed is not None:
            f = block.feed.evaluate(lookup)
            if not f > 0:
                raise ValueError(f"F{f:g}: the feed must be > 0 mm/min")
            self.feed = f
        # distance-control commands reach the controllers before the block's own motion starts; a
        # DIST_CTRL block takes its GEO cycle, so the next block sees its effect (e.g. OFF NO_MOVE
        # has handed the offset to the channel before the next move starts)
        for word in block.dist_ctrl:
            command = word.to_command(lookup, block.line, file=self.file)
            ch.dist_ctrl(word.axis, command)
            if word.wait:
                self._waits.append((word.axis, command.action))
        takes_time = bool(block.dist_ctrl)
        if block.dist_ctrl_3d:
            if not getattr(ch, "has_dist_ctrl_3d", False):
                raise NcAbort(UNKNOWN_NC_COMMAND, "Unknown Nc-command: #DIST CTRL needs 3D distance control "
                              "(P-CHAN-00500 configuration.decoder.function FCT_3D_DIST_CTRL)")
            for word in block.dist_ctrl_3d:
                command3d: Command3D = word.to_command3d(lookup, block.line, file=self.file)
                ch.dist_ctrl_3d(command3d)
                if command3d.wait:
                    self._waits_3d.append(command3d.action)
            takes_time = True          # like DIST_CTRL: the command takes its GEO cycle
        for word in block.kinematics:
            method = getattr(ch, "kinematics", None)
            if method is None:
                raise ValueError(f"#{word.kind.replace('_', ' ')}: this channel has no kinematics")
            method(word, lookup, block.line)
            takes_time = True          # the channel position is re-initialised in this cycle
        if block.axes:
            target = {}
            for axis, expr in block.axes.items():
                if axis not in ch.positions:
                    raise ValueError(f"axis {axis} is not configured in this channel")
                value = expr.evaluate(lookup)
                target[axis] = value if self.absolute else ch.positions[axis] + value
            if not self.rapid and self.feed is None:
                raise ValueError("G1 without a feed: program F")
            depth = 0 if self.rapid or block.ends_program else getattr(ch, "look_ahead", 0)
            ahead = self._prepare_ahead(dict(ch.positions), target, depth) if depth else ()
            if ahead:
                ch.start_linear(target, self.feed, ahead=ahead)
            else:
                ch.start_linear(target, None if self.rapid else self.feed)
            takes_time = True
        if block.dwell is not None:
            seconds = block.dwell.evaluate(lookup)
            if not seconds >= 0:
                raise ValueError(f"#TIME {seconds:g}: the dwell must be >= 0 s")
            ch.start_dwell(seconds)
            takes_time = True
        if block.wait_for is not None:
            self._wait_for = block.wait_for
            return not self._condition_holds()     # fulfilled at once: the next block in this cycle
        if block.ends_program:
            self.end_line = block.line
            if takes_time:
                self._end_pending = True
            else:
                self.ended = True
        return takes_time

    def _prepare_ahead(self, start: dict[str, float], target: dict[str, float],
                       depth: int) -> tuple[tuple[float, float], ...]:
        """(length mm, feed mm/min) of up to ``depth`` blocks after the current one that continue its
        line in its direction (module docstring, "Look-ahead"); read, not executed."""
        pos = dict(start)
        delta = {a: v - pos[a] for a, v in target.items() if v != pos[a]}
        length = math.hypot(*delta.values())
        if length == 0.0:
            return ()
        direction = {a: d / length for a, d in delta.items()}
        pos.update(target)
        absolute, feed = self.absolute, self.feed
        blocks = self.program.blocks
        out: list[tuple[float, float]] = []
        i = self.index
        while len(out) < depth and i < len(blocks):
            b = blocks[i]
            i += 1
            if b.is_empty:
                continue
            if (b.assignments or b.dist_ctrl or b.dist_ctrl_3d or b.kinematics or b.dwell is not None
                    or b.wait_for is not None or b.m_codes or not b.axes
                    or not _CHAIN_G_CODES.issuperset(b.g_codes)):
                break
            if 90 in b.g_codes:
                absolute = True
            elif 91 in b.g_codes:
                absolute = False
            try:
                if b.feed is not None:
                    feed = b.feed.evaluate(_constant)
                nxt = {}
                for a, expr in b.axes.items():
                    value = expr.evaluate(_constant)
                    nxt[a] = value if absolute else pos[a] + value
            except (ExprError, KeyError, ZeroDivisionError, OverflowError, ValueError):
                break
            if not (feed is not None and feed > 0):
                break
            d = {a: v - pos[a] for a, v in nxt.items() if v != pos[a]}
            n = math.hypot(*d.values())
            if n == 0.0 or d.keys() != direction.keys() \
                    or sum(d[a] * direction[a] for a in d) < n * (1.0 - 1e-9):
                break
            out.append((n, feed))
            pos.update(nxt)
        return tuple(out)


def program_end_command(line: int | None) -> Command:
    return Command(Action.PROGRAM_END, line=line)
