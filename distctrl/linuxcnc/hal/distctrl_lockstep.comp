component distctrl_lockstep "Lock-step gate between a servo thread and distctrl's userspace plant (distctrl linuxcnc bench)";
description """
distctrl's bench (docs/linuxcnc.md) runs LinuxCNC's components (plasmac, distctrl_thc) in a servo thread
of halrun and plays the machine around them from a userspace HAL component (Python's hal module). The
userspace side cannot keep a 1 ms period on a non-real-time kernel, so the thread waits for it: the
function *wait* (first in the thread) holds the period until the plant has written this period's
inputs (*ack* equals *seq*), the function *post* (last in the thread) counts the period (*seq* + 1),
which tells the plant that the components' outputs of this period are ready. Every period of the
components thus sees the plant's answer to the period before, in virtual time, and the run is
repeatable. What the wall clock did is counted, never hidden: *late* counts the periods that began
before the plant had answered (the thread waited; a real-time machine would have run them on stale
inputs), and
*missed* the periods the wait gave up after *timeout* seconds (the components then ran on stale
inputs; a bench run with missed > 0 is not lock-step).
""";
pin in u32 ack "the period whose inputs the plant has written (equal to seq: go)";
pin out u32 seq "periods completed";
pin out u32 late "periods that began before the plant had answered the period before (the thread waited)";
pin out u32 missed "periods the wait gave up (timeout): the components ran on stale inputs";
pin out float wait-max "longest wait for the plant (s)";
pin in bit enable "1: lock-step; 0: the thread runs free (seq still counts)";
pin in float timeout = 2.0 "give up waiting after this many seconds (counted in missed)";
function wait fp "first in the thread: wait for the plant's inputs of this period";
function post nofp "last in the thread: the period is done (seq + 1)";
license "GPL";
author "distctrl";
;;
#include <time.h>
#include <sched.h>

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

FUNCTION(wait) {
    double t0, waited;
    long spins = 0;
    struct timespec nap = {0, 20000};
    if (!enable || ack == seq)
        return;
    t0 = now_s();
    while (ack != seq && enable) {          /* enable off (the plant is done) releases the wait at once */
        if (++spins < 200)
            sched_yield();
        else
            nanosleep(&nap, NULL);
        if ((spins & 15) == 0 && now_s() - t0 > timeout) {
            missed = missed + 1;
            break;
        }
    }
    waited = now_s() - t0;
    if (waited > wait_max)
        wait_max = waited;
    late = late + 1;
}

FUNCTION(post) {
    seq = seq + 1;
}
