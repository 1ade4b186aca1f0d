// SPDX-License-Identifier: MIT
// Where a chain's stage times come from: the daemons time their stages by the steady clock (what
// a frame waits), the bench by the calling thread's CPU clock (what a stage costs on a machine
// shared with other work). The chain is the same code either way.
#pragma once

namespace telex {

using StageClock = double (*)();  // a reading in milliseconds; only differences mean anything

double steady_clock_ms();
double thread_cpu_ms();

}  // namespace telex
