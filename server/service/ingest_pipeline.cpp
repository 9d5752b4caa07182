// The ingest's processing network: the component kinds (matcher, store, grid, grid_lines), the default task file,
// and the stages a scan goes through.
//
// A scan's path, in the order of this file:
//   1. post_scan (an HTTP write thread): the scan and its ticket go into the matcher's queue; the thread waits on the
//      ticket's future.
//   2. decide_scan (matcher): a retried request id is answered from the store; else the scan's lines are extracted
//      and decided against the head map (the last one decided, committed or not), which they become.
//   3. commit_group (store): everything decided since the last group commits in one transaction (scan journal, lines,
//      decisions, request ids); a failure marks the group's epoch failed.
//   4. finish_committed (matcher, in commit order): the new map is published and the rules told; the commit's live
//      events begin (its update, the robot heard from); the ticket holds the answer; after a failure, what was decided
//      on top of it is dropped (resync_after_failure).
//   5. insert_grid_scans (grid): the scan goes into both grids; its grid event closes the commit's events; every
//      grid_trim_every scans a trim tick goes back to the matcher (decide_trim), and the scan's answer leaves when the
//      last stage holding its ticket lets go of it.
#include "server/service/ingest_pipeline.h"

#include <cmath>
#include <future>

#include "fusion/grid/scan_geometry.h"
#include "fusion/grid/sensor_model.h"
#include "server/service/map_recovery.h"
#include "server/service/service_errors.h"
#include "server/service/ticket.h"

namespace wm::service {

namespace {

using ScanTicket = Ticket<ScanOutcome>;
using PrimitivesTicket = Ticket<PrimitivesOutcome>;

}  // namespace

struct IngestPipeline::ScanJob {
  world::ScanObservation scan;
  std::string payload;  // a batch's scans: empty (the batch's body hash stands for it)
  std::optional<std::string> request_id;
  std::shared_ptr<ScanTicket> ticket;
};

// The scans of one request body, decided together and committed as one value.
struct IngestPipeline::ScanBatch {
  std::vector<ScanJobPtr> jobs;
  std::int64_t body_hash = 0;
};

namespace {

struct PrimitivesJob {
  world::Observation observation;
  std::string payload;
  std::optional<std::string> request_id;
  std::shared_ptr<PrimitivesTicket> ticket;  // null for the server's own observations (grid lines)
  std::shared_ptr<void> hold;                // a request answered only after this one is applied (or dropped)
};
using PrimitivesJobPtr = std::shared_ptr<PrimitivesJob>;
using Command = std::shared_ptr<std::function<void()>>;
struct GridTick {
  std::int64_t scan_seq = 0;
  std::shared_ptr<void> hold;  // the scan that made the extraction due is answered after it
};

}  // namespace

// A request decided on the matcher, on its way through the store and back.
struct IngestPipeline::Decided {
  std::uint64_t epoch = 0;
  ScanJobPtr scan;  // a scan (with its lines, if any) ...
  std::int64_t scan_seq = 0;
  PrimitivesJobPtr primitives;  // ... or posted primitives (neither: the server's own observation, a grid trim)
  std::optional<PreparedUpdate> update;
  std::optional<ScanPlacement> placement;  // a laser scan's, as its lines were extracted
  std::shared_ptr<void> hold;              // a request answered only after this one is applied (or failed)
  std::optional<storage::RequestRecord> request;
  std::string observation_payload;  // a scan's lines: {"scan": seq}
  std::exception_ptr error;         // the commit failed
  std::vector<DecidedPtr> members;  // a batch of scans: its scans, committed together (the fields above unused)
};

// A committed scan on its way into the grids, with its commit's live events (the scan event goes last).
struct IngestPipeline::GridScan {
  ScanJobPtr job;
  std::int64_t seq = 0;
  EventLog::Commit live;
};

std::string default_network_yaml() {
  return R"(description: >
  The default ingest network. Scans and primitives enter at the matcher, which extracts a laser scan's lines and
  decides them (and posted primitives) against the map as the requests before them leave it; the store writes what
  arrives together in one transaction; committed scans go into the Bayes and Dempster-Shafer grids; the grid line
  extractor runs on its own thread when it is due.
components:
  matcher: {kind: matcher}
  store: {kind: store, params: {max_batch: 64}}
  grid: {kind: grid}
  grid_lines: {kind: grid_lines}
subtasks:
  grid-lines: {components: [grid_lines], running: true}
connections:
  - matcher.decided -> store.in
  - store.committed -> matcher.committed
  - matcher.laser_scans -> grid.laser
  - matcher.sonar_scans -> grid.sonar
  - grid.trim -> matcher.trim
  - grid.extract -> grid_lines.tick
  - grid_lines.primitives -> matcher.primitives
executors:
  world: [matcher]
  storage: [store]
  grids: [grid]
  lines: [grid_lines]
)";
}

pipeline::Registry IngestPipeline::network_registry() {
  using pipeline::Component;
  using pipeline::InputOptions;
  using pipeline::PortPolicy;
  pipeline::Registry registry;
  const auto queued = options_.max_queued_requests;

  registry.add("matcher", [this, queued](const pipeline::Params&) {
    auto c = std::make_unique<Component>();
    c->input<ScanJobPtr>("laser", {PortPolicy::fifo, queued, true})
        .input<ScanJobPtr>("sonar", {PortPolicy::fifo, queued, true})
        .input<ScanBatchPtr>("scan_batches", {PortPolicy::fifo, queued, true})
        .input<PrimitivesJobPtr>("primitives", {PortPolicy::fifo, queued, true})
        .input<Command>("commands", {PortPolicy::fifo, queued, true})
        .input<DecidedPtr>("committed", {PortPolicy::fifo, 4 * queued, false})
        .input<TrimTick>("trim", {PortPolicy::latest, 1, false});
    c->output<DecidedPtr>("decided").output<GridScanPtr>("laser_scans").output<GridScanPtr>("sonar_scans");
    const auto nothing_in_flight = [this] { return in_flight_ == 0; };
    // Requests wait while a command waits for what is in flight: commands are never starved.
    const auto no_barrier = [this] { return network_->depth("matcher", "commands") == 0; };
    c->function("finish", {"committed"}, [this](pipeline::Activation& a) { finish_committed(a); },
                {{}, {}, std::vector<std::string>{"laser_scans", "sonar_scans"}});
    c->function("command", {"commands"}, [](pipeline::Activation& a) { (*a.take<Command>("commands"))(); },
                {{}, nothing_in_flight, std::vector<std::string>{}});
    // The trim is decided in the chain like a request (no barrier), before the scans waiting: it is tried first.
    c->function("trim", {"trim"}, [this](pipeline::Activation& a) { decide_trim(a); },
                {{}, no_barrier, std::vector<std::string>{"decided"}});
    c->function("laser", {"laser"}, [this](pipeline::Activation& a) { decide_scan(a, "laser"); },
                {{}, no_barrier, std::vector<std::string>{"decided"}});
    c->function("sonar", {"sonar"}, [this](pipeline::Activation& a) { decide_scan(a, "sonar"); },
                {{}, no_barrier, std::vector<std::string>{"decided"}});
    c->function("scan_batch", {"scan_batches"}, [this](pipeline::Activation& a) { decide_scan_batch(a); },
                {{}, no_barrier, std::vector<std::string>{"decided"}});
    c->function("primitives", {"primitives"}, [this](pipeline::Activation& a) { decide_primitives(a); },
                {{}, no_barrier, std::vector<std::string>{"decided"}});
    // One port each, so the order is the kind's: answers first, then commands, the trim, new requests.
    c->order({"finish", "command", "trim", "laser", "sonar", "scan_batch", "primitives"});
    c->on_thread_start(
        [this] { return std::static_pointer_cast<void>(std::make_shared<rules::ThreadAttachment>(engine_)); });
    return c;
  });

  registry.add("store", [this, queued](const pipeline::Params& params) {
    const auto batch = static_cast<std::size_t>(params.number("max_batch", 64, 1, 4096));
    auto c = std::make_unique<Component>();
    c->input<DecidedPtr>("in", {PortPolicy::fifo, queued, false, batch});
    c->output<DecidedPtr>("committed");
    c->function("commit", {"in"}, [this](pipeline::Activation& a) { commit_group(a); });
    return c;
  });

  registry.add("grid", [this, queued](const pipeline::Params& params) {
    // Every this many scans the grid asks the grid line extractor for a run (0: only POST /api/v1/grid/extract).
    // The same check at start and for a change at run time (PUT /api/v1/network/components/{name}/params).
    const auto read_extract_every = [this](const pipeline::Params& p) {
      return static_cast<std::int64_t>(
          p.number("extract_every", static_cast<double>(options_.grid_extract_every), 0, 1e9));
    };
    // Whether sonar is judged by the laser before the fused grid takes it (wmd --sonar-gate by default).
    const auto read_sonar_gate = [this](const pipeline::Params& p) {
      const auto text = p.text("sonar_gate");
      if (!text) return grid_.sonar().gated;
      if (*text != "on" && *text != "off" && *text != "true" && *text != "false")
        throw std::invalid_argument("parameter 'sonar_gate' must be on or off, not '" + *text + "'");
      return *text == "on" || *text == "true";
    };
    grid_.set_sonar_gate(read_sonar_gate(params));  // before any executor runs
    // Read and written on the grid's executor thread only.
    auto extract_every = std::make_shared<std::int64_t>(read_extract_every(params));
    auto c = std::make_unique<Component>();
    c->input<GridScanPtr>("laser", {PortPolicy::fifo, 4 * queued, false})
        .input<GridScanPtr>("sonar", {PortPolicy::fifo, 4 * queued, false});
    c->output<TrimTick>("trim").output<GridTick>("extract");
    c->function("laser_and_sonar", {"laser", "sonar"},
                [this, extract_every](pipeline::Activation& a) { insert_grid_scans(a, true, true, *extract_every); });
    c->function("laser", {"laser"},
                [this, extract_every](pipeline::Activation& a) { insert_grid_scans(a, true, false, *extract_every); });
    c->function("sonar", {"sonar"},
                [this, extract_every](pipeline::Activation& a) { insert_grid_scans(a, false, true, *extract_every); });
    c->order({"laser", "sonar"});
    c->settable(
        {{"extract_every", std::to_string(*extract_every)}, {"sonar_gate", grid_.sonar().gated ? "on" : "off"}},
        [this, read_extract_every, read_sonar_gate, extract_every](const pipeline::Params& p) -> std::function<void()> {
          const auto value = read_extract_every(p);
          const bool gate = read_sonar_gate(p);
          return [this, extract_every, value, gate] {
            *extract_every = value;
            grid_.set_sonar_gate(gate);
          };
        });
    return c;
  });

  registry.add("grid_lines", [this](const pipeline::Params&) {
    auto c = std::make_unique<Component>();
    c->input<GridTick>("tick", {PortPolicy::latest, 1, false});
    c->output<PrimitivesJobPtr>("primitives");
    // Off the matcher's thread: thinning and Hough over the whole grid take tens to hundreds of milliseconds.
    c->function("extract", {"tick"}, [this](pipeline::Activation& a) {
      const auto tick = a.take<GridTick>("tick");
      const auto raster = grid_.probability_raster();
      if (!raster) return;
      const auto segments = fusion::extract_grid_lines(*raster, options_.grid_lines);
      if (segments.empty()) return;
      auto job = std::make_shared<PrimitivesJob>();
      job->observation = grid_lines_observation(segments);
      job->payload = grid_lines_payload(tick.scan_seq);
      job->hold = tick.hold;
      a.emit("primitives", std::move(job));
    });
    return c;
  });
  return registry;
}

IngestPipeline::IngestPipeline(const IngestOptions& options, IngestParts parts)
    : options_(options),
      store_(parts.store),
      engine_(parts.engine),
      writer_(parts.writer),
      grid_(parts.grid),
      plan_checks_(parts.plan_checks),
      robots_(parts.robots),
      events_(parts.events),
      diagnostics_(parts.diagnostics) {
  head_ = writer_.snapshot();
  const std::int64_t last_scan_seq = grid_.last_scan_seq();
  next_scan_seq_ = committed_scan_seq_ = last_scan_seq;
  // The grid trim looks at what the scans since the last one could see: rebuilt from the journal, so a restart trims
  // as an uninterrupted run would. A crash between a scan and the trim it made due leaves that trim undone: it is
  // made at start (trim_left_undone), against the same map and grid the run had then (the journal ends at that scan).
  if (options_.grid_trim_every > 0 && last_scan_seq > 0) {
    const auto every = static_cast<std::int64_t>(options_.grid_trim_every);
    auto since = last_scan_seq - last_scan_seq % every;
    const bool due = last_scan_seq % every == 0 && !store_.has_observation(kTrimObserver, trim_payload(last_scan_seq));
    if (due) since = last_scan_seq - every;
    for_each_journaled_scan(store_, since, [this](std::int64_t seq, storage::JournaledScan&& record) {
      try {
        add_to_trim_region(journaled_scan(std::move(record)));
      } catch (const std::exception& e) {
        diagnostics_.report(common::Severity::warning, "grid_trim",
                            "scan " + std::to_string(seq) + " left out of the grid trim: " + e.what());
      }
    });
    if (due && trim_region_) {
      trim_left_undone_.emplace(last_scan_seq, *trim_region_);
      trim_region_.reset();
    }
  }
  const auto spec = options_.network_file ? pipeline::read_task_file(options_.network_file->string())
                                          : pipeline::parse_task(default_network_yaml(), "<default network>");
  // A function that throws is a bug: counted in the network's stats, and reported here with what it said.
  network_ = std::make_unique<pipeline::Network>(
      spec, network_registry(), [this](std::string_view component, std::string_view function, std::string_view what) {
        diagnostics_.report(common::Severity::error, "network",
                            std::string(component) + "." + std::string(function) + " failed: " + std::string(what));
      });
  network_->start();
}

IngestPipeline::~IngestPipeline() { stop(); }

void IngestPipeline::stop() {
  if (stopped_) return;
  stopped_ = true;
  const auto report = network_->stop(true);
  for (const auto& [port, count] : report.dropped)
    diagnostics_.report(
        common::Severity::warning, "network",
        "stopped with " + std::to_string(count) + " values left in " + port + " (their requests got 503)");
}

void IngestPipeline::submit_command(std::function<void()> job) {
  try {
    network_->inject("matcher", "commands", std::make_shared<std::function<void()>>(std::move(job)));
  } catch (const pipeline::QueueFull& e) {
    throw Busy(std::string("the world model's command queue is full; retry later (") + e.what() + ")");
  }
}

ScanOutcome IngestPipeline::post_scan(world::ScanObservation scan, std::string payload_json,
                                      std::optional<std::string> request_id) {
  const std::string sensor = scan.sensor();
  if (!accepts_scans(sensor))
    throw std::invalid_argument("the processing network (" + network_->source() + ") does not process " + sensor +
                                " scans");
  auto job = std::make_shared<ScanJob>(
      ScanJob{std::move(scan), std::move(payload_json), std::move(request_id), std::make_shared<ScanTicket>()});
  auto future = job->ticket->future();
  try {
    network_->inject("matcher", sensor, std::move(job));
  } catch (const pipeline::QueueFull& e) {
    throw Busy(std::string("the world model's scan queue is full; retry later (") + e.what() + ")");
  }
  return future.get();
}

std::vector<ScanOutcome> IngestPipeline::post_scans(std::vector<world::ScanObservation> scans, std::string_view body,
                                                    std::optional<std::string> request_id) {
  if (scans.empty()) throw std::invalid_argument("post_scans: a batch needs at least one scan");
  for (const auto& scan : scans)
    if (!accepts_scans(scan.sensor()))
      throw std::invalid_argument("the processing network (" + network_->source() + ") does not process " +
                                  scan.sensor() + " scans");
  auto batch = std::make_shared<ScanBatch>();
  batch->body_hash = body_hash(body);
  std::vector<std::future<ScanOutcome>> futures;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    // Each scan keeps its own record under the batch's id, so a retried batch is answered scan by scan.
    auto id = request_id ? std::optional<std::string>(*request_id + "[" + std::to_string(i) + "]") : std::nullopt;
    auto job = std::make_shared<ScanJob>(
        ScanJob{std::move(scans[i]), std::string(), std::move(id), std::make_shared<ScanTicket>()});
    futures.push_back(job->ticket->future());
    batch->jobs.push_back(std::move(job));
  }
  try {
    network_->inject("matcher", "scan_batches", std::move(batch));
  } catch (const pipeline::QueueFull& e) {
    throw Busy(std::string("the world model's scan queue is full; retry later (") + e.what() + ")");
  }
  std::vector<ScanOutcome> outcomes;
  outcomes.reserve(futures.size());
  for (auto& future : futures) outcomes.push_back(future.get());  // the batch's error, if any, is every scan's
  return outcomes;
}

PrimitivesOutcome IngestPipeline::post_primitives(world::Observation observation, std::string payload_json,
                                                  std::optional<std::string> request_id) {
  auto job = std::make_shared<PrimitivesJob>(PrimitivesJob{std::move(observation), std::move(payload_json),
                                                           std::move(request_id), std::make_shared<PrimitivesTicket>(),
                                                           nullptr});
  auto future = job->ticket->future();
  try {
    network_->inject("matcher", "primitives", std::move(job));
  } catch (const pipeline::QueueFull& e) {
    throw Busy(std::string("the world model's primitives queue is full; retry later (") + e.what() + ")");
  }
  return future.get();
}

bool IngestPipeline::accepts_scans(const std::string& sensor) const { return network_->consumes("matcher", sensor); }

pipeline::NetworkStats IngestPipeline::stats() const { return network_->stats(); }

void IngestPipeline::set_subtask(const std::string& name, bool running) {
  try {
    network_->set_subtask(name, running);
  } catch (const std::out_of_range& e) {
    throw NotFound(e.what());
  } catch (const pipeline::QueueFull& e) {
    throw Busy(e.what());
  }
}

void IngestPipeline::set_params(const std::string& component, const std::map<std::string, std::string>& changes) {
  try {
    network_->set_params(component, changes);
  } catch (const std::out_of_range& e) {
    throw NotFound(e.what());
  } catch (const pipeline::QueueFull& e) {
    throw Busy(e.what());
  }
}

// On the matcher, from finish only: the groups committed before the failed one are finished (and published) by then,
// and what was decided after it carries its epoch and fails in the store.
void IngestPipeline::resync_after_failure() {
  if (failed_epoch_ < epoch_) return;
  epoch_ = failed_epoch_ + 1;
  // What was decided on top of the failed group fails in the store too; the next request starts from the committed
  // map.
  head_ = writer_.snapshot();
  next_scan_seq_ = committed_scan_seq_;
  writer_.restore_facts(*head_, "a failed commit");
}

void IngestPipeline::decide_scan(pipeline::Activation& a, const std::string& port) {
  refresh_head();
  auto job = a.take<ScanJobPtr>(port);
  try {
    const auto hash = body_hash(job->payload);
    if (job->request_id) {
      if (pending_request_ids_.count(*job->request_id))
        throw Busy("request id '" + *job->request_id + "' is being applied; retry to get its answer");
      if (auto replayed = replayed_scan(job->request_id, hash, job->scan)) {
        job->ticket->succeed(std::move(*replayed));
        return;
      }
    }
    a.emit("decided", decide_scan_job(job, hash));
  } catch (...) {
    job->ticket->fail(std::current_exception());
  }
}

IngestPipeline::DecidedPtr IngestPipeline::decide_scan_job(ScanJobPtr job, std::int64_t hash) {
  auto d = std::make_shared<Decided>();
  d->epoch = epoch_;
  d->scan_seq = next_scan_seq_ + 1;
  d->update = prepare_scan_lines(job->scan, d->placement);
  d->observation_payload = "{\"scan\": " + std::to_string(d->scan_seq) + "}";
  if (job->request_id) {
    d->request = storage::RequestRecord{*job->request_id,
                                        "scan",
                                        hash,
                                        d->scan_seq,
                                        d->update ? d->update->update.state.version : 0,
                                        d->scan_seq,
                                        d->update ? std::optional<std::int64_t>(d->update->seq) : std::nullopt};
    pending_request_ids_[*job->request_id] = hash;
  }
  if (d->update) head_ = std::make_shared<const world::WorldState>(d->update->update.state);
  next_scan_seq_ = d->scan_seq;
  d->scan = std::move(job);
  ++in_flight_;
  return d;
}

void IngestPipeline::decide_scan_batch(pipeline::Activation& a) {
  refresh_head();
  auto batch = a.take<ScanBatchPtr>("scan_batches");
  const auto fail_all = [&batch](const std::exception_ptr& error) {
    for (const auto& job : batch->jobs) job->ticket->fail(error);
  };
  try {
    // A retried batch: every scan is answered from its record, or the batch is applied whole.
    std::vector<ScanOutcome> replayed;
    for (const auto& job : batch->jobs) {
      if (job->request_id && pending_request_ids_.count(*job->request_id))
        throw Busy("request id '" + *job->request_id + "' is being applied; retry to get its answer");
      if (auto answer = replayed_scan(job->request_id, batch->body_hash, job->scan))
        replayed.push_back(std::move(*answer));
    }
    if (!replayed.empty() && replayed.size() != batch->jobs.size())
      throw RequestIdConflict("request id '" + batch->jobs.front()->request_id.value_or("") +
                              "' and the others of this batch were not all used before: a batch is retried whole");
    if (!replayed.empty()) {
      for (std::size_t i = 0; i < replayed.size(); ++i) batch->jobs[i]->ticket->succeed(std::move(replayed[i]));
      return;
    }
  } catch (...) {
    fail_all(std::current_exception());
    return;
  }
  const auto head_before = head();
  const auto seq_before = next_scan_seq_;
  auto whole = std::make_shared<Decided>();
  whole->epoch = epoch_;
  try {
    for (const auto& job : batch->jobs) whole->members.push_back(decide_scan_job(job, batch->body_hash));
  } catch (...) {
    // Nothing of the batch goes on: the head, the scan sequence and the rules' facts are as before its first scan.
    bool changed_map = false;
    for (const auto& member : whole->members) {
      if (member->request) pending_request_ids_.erase(member->request->request_id);
      changed_map = changed_map || member->update.has_value();
      --in_flight_;
    }
    head_ = head_before;
    next_scan_seq_ = seq_before;
    if (changed_map) writer_.restore_facts(*head_, "a refused batch of scans");
    fail_all(std::current_exception());
    return;
  }
  ++in_flight_;  // the batch itself, until its members are finished
  a.emit("decided", std::move(whole));
}

void IngestPipeline::decide_primitives(pipeline::Activation& a) {
  refresh_head();
  auto job = a.take<PrimitivesJobPtr>("primitives");
  try {
    const auto hash = body_hash(job->payload);
    if (job->request_id) {
      if (pending_request_ids_.count(*job->request_id))
        throw Busy("request id '" + *job->request_id + "' is being applied; retry to get its answer");
      if (const auto known = known_request(*job->request_id, "primitives", hash)) {
        job->ticket->succeed(
            PrimitivesOutcome{known->seq, known->version, store_.observation_decisions(known->seq), true});
        return;
      }
    }
    auto d = std::make_shared<Decided>();
    d->epoch = epoch_;
    d->update = writer_.prepare(head(), std::move(job->observation));
    if (job->request_id) {
      d->request = storage::RequestRecord{
          *job->request_id, "primitives", hash, d->update->seq, d->update->update.state.version, 0, std::nullopt};
      pending_request_ids_[*job->request_id] = hash;
    }
    head_ = std::make_shared<const world::WorldState>(d->update->update.state);
    d->primitives = std::move(job);
    ++in_flight_;
    a.emit("decided", std::move(d));
  } catch (...) {
    if (job->ticket) {
      job->ticket->fail(std::current_exception());
    } else {
      try {
        throw;
      } catch (const std::exception& e) {
        diagnostics_.report(common::Severity::error, "grid_lines",
                            std::string("the grid line extractor's observation was not applied: ") + e.what());
      }
    }
  }
}

void IngestPipeline::decide_trim(pipeline::Activation& a) {
  refresh_head();
  auto tick = a.take<TrimTick>("trim");
  auto p = prepare_trim(tick.region);
  if (!p) return;
  auto d = std::make_shared<Decided>();
  d->epoch = epoch_;
  d->update = std::move(*p);
  d->observation_payload = trim_payload(tick.scan_seq);
  d->hold = std::move(tick.ticket);
  head_ = std::make_shared<const world::WorldState>(d->update->update.state);
  ++in_flight_;
  a.emit("decided", std::move(d));
}

void IngestPipeline::commit_group(pipeline::Activation& a) {
  auto group = a.take_all<DecidedPtr>("in");
  std::vector<DecidedPtr> valid;
  for (auto& d : group) {
    if (d->epoch <= failed_epoch_)
      d->error = std::make_exception_ptr(Busy("an earlier request it was decided after could not be stored; retry"));
    else
      valid.push_back(d);
  }
  if (!valid.empty()) {
    try {
      // A batch of scans is its scans, in order.
      std::vector<const Decided*> parts;
      for (const auto& d : valid) {
        if (d->members.empty()) parts.push_back(d.get());
        for (const auto& member : d->members) parts.push_back(member.get());
      }
      std::vector<storage::Store::BatchEntry> entries;
      std::vector<storage::ScanEntry> scans;
      scans.reserve(parts.size());
      entries.reserve(parts.size());
      for (const auto* d : parts) {
        storage::Store::BatchEntry entry;
        if (d->scan) {
          scans.push_back(storage::ScanEntry{d->scan_seq, &d->scan->scan});
          entry.scan = scans.back();
          if (d->update)
            entry.observation.emplace(
                storage::ObservationEntry{d->update->update, d->update->observation, d->observation_payload});
        } else {
          entry.observation.emplace(storage::ObservationEntry{
              d->update->update, d->update->observation,
              d->primitives ? std::string_view(d->primitives->payload) : std::string_view(d->observation_payload)});
        }
        entry.request = d->request;
        entries.push_back(std::move(entry));
      }
      store_.commit_batch(entries);
    } catch (...) {
      const auto error = std::current_exception();
      std::uint64_t epoch = failed_epoch_;
      for (auto& d : valid) {
        d->error = error;
        epoch = std::max(epoch, d->epoch);
      }
      failed_epoch_ = epoch;
    }
  }
  for (auto& d : group) a.emit("committed", std::move(d));
}

void IngestPipeline::finish_committed(pipeline::Activation& a) {
  auto d = a.take<DecidedPtr>("committed");
  for (auto& member : d->members) {
    if (d->error) member->error = d->error;
    finish_decided(a, std::move(member));
  }
  if (!d->members.empty()) {
    --in_flight_;
    return;
  }
  finish_decided(a, std::move(d));
}

void IngestPipeline::finish_decided(pipeline::Activation& a, DecidedPtr d) {
  --in_flight_;
  if (d->request) pending_request_ids_.erase(d->request->request_id);
  if (d->error) {
    resync_after_failure();
    if (d->scan)
      d->scan->ticket->fail(d->error);
    else if (d->primitives && d->primitives->ticket)
      d->primitives->ticket->fail(d->error);
    else
      diagnostics_.report(common::Severity::error, "store",
                          std::string("the server's own observation (") + (d->primitives ? "grid lines" : "grid trim") +
                              ") was not stored");
    return;
  }
  // The commit's events: its update, the robot heard from, and (a scan, on the grid thread) the grid region.
  auto live = events_.begin();
  const std::string observer = d->update ? d->update->observation.observer : std::string();
  std::optional<PrimitivesOutcome> lines;
  if (d->update) lines = writer_.finish(std::move(*d->update), live);
  if (!d->scan) {
    if (d->primitives && d->primitives->ticket) {
      add_robot_event(live, robots_, robots_.on_primitives(observer, now_unix_s()));
      d->primitives->ticket->succeed(std::move(*lines));
    }
    return;
  }
  committed_scan_seq_ = d->scan_seq;
  const auto& scan = d->scan->scan;
  add_robot_event(live, robots_, robots_.on_scan(scan.observer, scan.sensor(), scan_pose(scan, now_unix_s())));
  d->scan->ticket->succeed(ScanOutcome{d->scan_seq, d->scan_seq, std::move(lines), false, d->placement});
  const bool laser = std::holds_alternative<fusion::LaserScan>(scan.scan);
  a.emit(laser ? "laser_scans" : "sonar_scans",
         std::make_shared<GridScan>(GridScan{std::move(d->scan), d->scan_seq, std::move(live)}));
}

void IngestPipeline::insert_grid_scans(pipeline::Activation& a, bool laser, bool sonar, std::int64_t extract_every) {
  // Laser and sonar scans come on two queues, each in journal order, but not in journal order with each other
  // (laser 10 and 11 may be queued while sonar 12 is taken). The grid takes them in journal order: a sonar reading
  // is judged by the laser scans before it, exactly as a replay of the journal judges it. A scan waits here for
  // the ones before it (they are on the other queue, on their way).
  const auto hold = [this](GridScanPtr s) {
    const auto seq = s->seq;
    grid_held_.emplace(seq, std::move(s));
  };
  if (laser) hold(a.take<GridScanPtr>("laser"));
  if (sonar) hold(a.take<GridScanPtr>("sonar"));
  std::vector<GridScanPtr> scans;
  for (std::int64_t next = grid_.last_scan_seq() + 1; !grid_held_.empty();) {
    const auto first = grid_held_.begin();
    if (first->first > next) {
      if (grid_held_.size() <= kMaxHeldGridScans) break;
      // Never seen: every journaled scan is sent to the grid. Rather than hold every later scan for ever:
      diagnostics_.report(common::Severity::error, "grid",
                          "scan " + std::to_string(next) + " never reached the grid; scan " +
                              std::to_string(first->first) + " goes in without it");
    }
    next = first->first + 1;
    scans.push_back(std::move(first->second));
    grid_held_.erase(first);
  }
  if (scans.empty()) return;
  const auto state = writer_.snapshot();
  for (const auto& s : scans) {
    try {
      grid_.insert(s->job->scan, s->seq, *state);
    } catch (const std::exception& e) {
      // Validated at the HTTP boundary, so this is a bug; the scan is journaled and counted all the same.
      diagnostics_.report(common::Severity::error, "grid",
                          "scan " + std::to_string(s->seq) + " not inserted into the grid: " + e.what());
    }
  }
  try {
    grid_.flush(false);
  } catch (const std::exception& e) {
    diagnostics_.report(
        common::Severity::warning, "grid",
        std::string("grid flush failed (the journal has every scan; retried at the next flush): ") + e.what());
  }
  for (const auto& s : scans) {
    add_scan_event(s->live, s->job->scan, s->seq);
    s->live.close();
    if (extract_every > 0 && s->seq % extract_every == 0) a.emit("extract", GridTick{s->seq, s->job->ticket});
    if (options_.grid_trim_every == 0) continue;
    try {
      add_to_trim_region(s->job->scan);
    } catch (const std::exception& e) {
      diagnostics_.report(common::Severity::warning, "grid_trim",
                          "scan " + std::to_string(s->seq) + " left out of the grid trim: " + e.what());
    }
    // The scan is answered after the trim it makes due, so a client that posts one scan at a time sees the same map
    // as before the network (and a replay stays deterministic). The tick takes the region of exactly the scans since
    // the last trim, so what a trim looks at does not depend on when the matcher gets to it.
    if (s->seq % static_cast<std::int64_t>(options_.grid_trim_every) == 0) {
      std::optional<world::Box> region;
      {
        std::lock_guard lock(trim_mutex_);
        region.swap(trim_region_);
      }
      if (region) a.emit("trim", TrimTick{s->seq, *region, s->job->ticket});
    }
  }
}

}  // namespace wm::service
