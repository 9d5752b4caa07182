#pragma once

// Start of the process-wide SWI-Prolog runtime and loading of the support module. Internal to
// rules::Engine, which calls them from its constructor.

namespace wm::rules::internal {

/// Initialises the SWI-Prolog runtime once per process (a later call returns at once) and registers
/// the foreign predicates of the support module. Keeps LC_NUMERIC "C" and the host's process-control
/// signal dispositions. @throw RuleError when the runtime does not start or a registration fails.
void initialise_runtime();

/// Loads the support modules from the texts embedded at build time: wm_rule_checks (rule_checks.pl),
/// then wm_engine (engine_support.pl), which imports from it; once per process (a later call returns
/// at once): loading them again would reset the state of the Engines that use them. Needs an attached
/// thread.
/// @throw RuleError when one does not load.
void load_support_module();

}  // namespace wm::rules::internal
