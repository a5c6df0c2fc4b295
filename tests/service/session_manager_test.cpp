// The session manager on the simulated cell (real client over TCP, real USB protocol code, real
// journal on disk): the states and events of a session, one session at a time, refusals, abort,
// resume, results and the live PSD reading.
#include "zerocal/service/session_manager.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <future>
#include <mutex>
#include <thread>

#include "stored_plan_request.h"
#include "zerocal/apply/online_apply.h"
#include "zerocal/cell/link_error.h"
#include "zerocal/io/joint_set.h"
#include "zerocal/record/sqlite_record.h"
#include "zerocal/report/session_report.h"
#include "zerocal/sim/sim_backend.h"
#include "zerocal/sim/sim_controller.h"
#include "zerocal/sim/world.h"

namespace zerocal::service {
namespace {

struct TempDir {
  TempDir() {
    char pattern[] = "/tmp/zerocal-manager-XXXXXX";
    if (!::mkdtemp(pattern)) throw std::runtime_error("mkdtemp failed");
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string path;
};

// The ideal world: the manager's results are checked against the truth (docs/simulated-cell.md).
// Sessions run on the optimal planner's plan for the seed's world, stored in tests/data/plans
// ("ideal-<seed>"), so that start() does not plan for seconds; only the test of an abort while
// planning plans.
sim::SimulatedCellOptions cellFor(std::uint64_t seed) {
  return sim::seededCellOptions(seed, WorldKind::kIdeal);
}

ManagerSettings settingsIn(const std::string& dir) {
  ManagerSettings s;
  s.session.data_dir = dir;
  s.run.servo.stop = servo::ServoStop::kZone;
  s.session.noise_mm = 0.020;  // the simulated repeatability at the detector
  return s;
}

// Every event the manager emits, in order.
struct EventLog {
  std::mutex mutex;
  std::condition_variable arrived;
  std::vector<SessionEvent> events;
  std::function<void(const SessionEvent&)> also;
  SessionControl::EventSink sink() {
    return [this](const SessionEvent& e) {
      {
        std::lock_guard<std::mutex> lock(mutex);
        events.push_back(e);
      }
      arrived.notify_all();
      if (also) also(e);
    };
  }
  // The events of a type once there are `count` of them (or after 10 s, however many came): an
  // event goes out after the state change it follows, so a status can be seen before it.
  template <class Event>
  std::vector<Event> atLeast(std::size_t count) {
    {
      std::unique_lock<std::mutex> lock(mutex);
      arrived.wait_for(lock, std::chrono::seconds(10), [&] {
        std::size_t n = 0;
        for (const auto& e : events) n += std::holds_alternative<Event>(e);
        return n >= count;
      });
    }
    return of<Event>();
  }
  template <class Event>
  std::vector<Event> of() {
    std::lock_guard<std::mutex> lock(mutex);
    std::vector<Event> out;
    for (const auto& e : events)
      if (const auto* event = std::get_if<Event>(&e)) out.push_back(*event);
    return out;
  }
};

// The 1-based plan pose of a pose event; 0 for any other event.
int recordedPose(const SessionEvent& e) {
  const auto* pose = std::get_if<PoseEvent>(&e);
  return pose ? pose->record.planIndex() + 1 : 0;
}

std::vector<int> journalIndices(const std::string& path) {
  std::vector<int> indices;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);)
    indices.push_back(nlohmann::json::parse(line)["index"].get<int>());
  return indices;
}

TEST(SessionManager, RunsASessionToDoneThroughEveryStateWithAResultNearTheTruth) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(5));
  SessionManager manager(backend, settingsIn(dir.path));
  EventLog log;
  manager.setEventSink(log.sink());
  EXPECT_EQ(manager.status().state, SessionState::kIdle);
  const StartRequest request = testing::onStoredPlan(manager.defaultRequest(), "ideal-5");
  EXPECT_EQ(manager.preview(request).prediction.cell_time_sessions, 0)
      << "no session yet to predict its cell time from";

  const std::string id = manager.start(request);
  // Polled as a terminal would: the live servo error shows while servoing, and only then.
  int live_seen = 0, polls = 0, servoing = 0, any = 0;
  double cell_time_s = 0;
  for (SessionStatus s = manager.status(); isActive(s.state); s = manager.status()) {
    std::this_thread::sleep_for(std::chrono::microseconds(200));
    ++polls;
    EXPECT_LE(s.pose, s.pose_count) << stateName(s.state);  // solving is not "pose 9 of 8"
    EXPECT_GE(s.cell_time_s, cell_time_s);                  // the cell time runs during the session
    cell_time_s = s.cell_time_s;
    if (s.state == SessionState::kServoing) ++servoing;
    if (s.live_servo_error_um) {
      EXPECT_EQ(s.state, SessionState::kServoing);
      ++any;
      if (std::isfinite(*s.live_servo_error_um)) {
        EXPECT_LT(*s.live_servo_error_um, 5000.0);  // on the 10 mm detector
        ++live_seen;
      }
    }
  }
  EXPECT_GT(live_seen, 0) << polls << " polls, " << servoing << " servoing, " << any << " any";
  EXPECT_GT(cell_time_s, 10.0);  // seen before the end: 8 poses take tens of cell seconds
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  EXPECT_EQ(end.session_id, id);
  // Poses the first solve named are measured once more (at most 3): journal lines beyond the 8.
  const nlohmann::json remeasured = toJson(manager.result(id))["remeasured"];
  ASSERT_TRUE(remeasured.is_array());
  ASSERT_LE(remeasured.size(), 3u);
  const int again = static_cast<int>(remeasured.size());
  EXPECT_EQ(end.recorded, 8 + again);
  EXPECT_EQ(end.achieved_sigma_deg.size(), 4u);
  EXPECT_EQ(end.predicted_sigma_deg.size(), 4u);

  // The states in the order a technician would see them.
  std::vector<std::string> states;
  for (const auto& e : log.of<StateEvent>()) {
    const std::string s = stateName(e.state);
    if (states.empty() || states.back() != s) states.push_back(s);
  }
  ASSERT_GE(states.size(), 6u);
  EXPECT_EQ(states.front(), "connecting");
  EXPECT_EQ(states[1], "moving");
  EXPECT_EQ(states[2], "servoing");
  EXPECT_EQ(states[3], "recording");
  EXPECT_EQ(states[states.size() - 2], "solving");
  EXPECT_EQ(states.back(), "done");
  // One pose event per pose, 1..8, each with its servo figures; then one per pose measured again,
  // announced by a remeasure event.
  const auto poses = log.of<PoseEvent>();
  ASSERT_EQ(poses.size(), 8u + again);
  for (int i = 0; i < 8 + again; ++i) {
    EXPECT_EQ(poses[i].record.planIndex() + 1, i < 8 ? i + 1 : remeasured[i - 8].get<int>());
    EXPECT_EQ(poses[i].record.remeasure_of >= 0, i >= 8);
    EXPECT_EQ(poses[i].pose_count, 8);
    EXPECT_TRUE(poses[i].record.measured());
    EXPECT_GE(poses[i].record.servo.moves, 0);
  }
  ASSERT_EQ(log.of<RemeasureEvent>().size(), again > 0 ? 1u : 0u);
  if (again > 0) {
    EXPECT_EQ(nlohmann::json(log.of<RemeasureEvent>()[0].poses), remeasured);
  }
  ASSERT_EQ(log.of<PlanEvent>().size(), 1u);
  EXPECT_EQ(log.of<PlanEvent>()[0].predicted_sigma_deg, end.predicted_sigma_deg);
  ASSERT_EQ(log.of<ResultEvent>().size(), 1u);
  EXPECT_EQ(log.of<ResultEvent>()[0].achieved_sigma_deg, end.achieved_sigma_deg);

  const nlohmann::json result = toJson(manager.result(id));
  EXPECT_EQ(result, toJson(manager.result("")));  // the latest finished one
  for (int k = 0; k < kOffsetCount; ++k) {
    const std::string name = unknownName(k);
    const double error =
        result["parameters"][name]["value"].get<double>() - result["truth"][name].get<double>();
    EXPECT_LT(std::abs(error), 4 * result["parameters"][name]["sigma"].get<double>()) << name;
  }
  EXPECT_GT(result["cell_time_s"].get<double>(), 0);
  EXPECT_EQ(result["pose_breakdown"].size(), 8u + again);
  // Each pose weighed by its own noise, from the configuration's joint repeatability (the
  // default): the result says so, and its noise_mm is the model's reference sigma.
  EXPECT_EQ(result["noise_source"], "per pose, from the joints' repeatability");
  EXPECT_EQ(result["joint_repeatability_deg"].get<double>(),
            SessionConfig{}.joint_repeatability_deg);
  EXPECT_NEAR(result["noise_mm"].get<double>(), 1.5e-3 * kDegToRad * 1000, 1e-4);
  // Whose result: the robot as the (simulated) controller named itself, the map that read the
  // PSD, this zerocal, and when.
  const SimControllerOptions controller;
  EXPECT_EQ(result["cell"]["controller"]["serial"], controller.serial);
  EXPECT_EQ(result["cell"]["controller"]["robot_type"], controller.robot_type);
  EXPECT_EQ(result["cell"]["controller"]["software_version"], controller.software_version);
  EXPECT_EQ(result["cell"]["psd_map"],
            "simulated bench sweep, fingerprint " + backend.cell().psdMap().fingerprint());
  EXPECT_FALSE(result["zerocal_version"].get<std::string>().empty());
  const auto now_s = std::chrono::duration_cast<std::chrono::seconds>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count();
  EXPECT_NEAR(result["finished_unix_s"].get<double>(), static_cast<double>(now_s), 600);
  // Every line is kept: the first measurements of the poses measured again too.
  const JournalContents journal = readJournal(dir.path + "/" + id + "/journal.jsonl");
  ASSERT_EQ(journal.records.size(), 8u + again);
  for (int i = 0; i < 8 + again; ++i) {
    EXPECT_EQ(journal.records[i].index, i);
    EXPECT_EQ(journal.records[i].remeasure_of, i < 8 ? -1 : remeasured[i - 8].get<int>() - 1);
  }
  // Each residual names the journal line it was solved from: each plan pose's latest line.
  const std::vector<const PoseRecord*> latest = latestRecords(journal.records);
  ASSERT_EQ(result["pose_residuals"].size(), latest.size());
  for (std::size_t k = 0; k < latest.size(); ++k)
    EXPECT_EQ(result["pose_residuals"][k]["line"], latest[k]->line) << "pose " << k + 1;
  // The whole simulated world beside the result: it reads back to the cell's world.
  ASSERT_EQ(result["truth"]["world_file"], "truth-world.yaml");
  const World truth = loadWorld(dir.path + "/" + id + "/truth-world.yaml");
  const World& simulated = backend.cell().world();
  EXPECT_EQ(truth.true_offsets_deg, simulated.true_offsets_deg);
  EXPECT_EQ(truth.psd_centre_taught_mm, simulated.psd_centre_taught_mm);
  EXPECT_EQ(truth.gross.stray_light_rate, simulated.gross.stray_light_rate);
  // The next plan's cell time, from what a pose cost this session.
  const Plan next = manager.preview(request);
  EXPECT_EQ(next.prediction.cell_time_sessions, 1);
  const double per_pose = result["cell_time_s"].get<double>() / result["poses"].get<double>();
  EXPECT_DOUBLE_EQ(next.prediction.cell_time_per_pose_s, per_pose);
  EXPECT_DOUBLE_EQ(next.prediction.cell_time_s, static_cast<double>(next.poses.size()) * per_pose);
}

// The disk fills up at the end of a session: the result is on disk, the report cannot be
// written. The session is done, but its status and its events say the report is missing and why,
// and no half-written report is left behind.
TEST(SessionManager, AReportThatCannotBeWrittenIsNamedInTheStatusAndTheEvents) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(5));
  ManagerSettings settings = settingsIn(dir.path);
  settings.write_reports = [](const std::string& session_dir,
                              const std::vector<record::HistoryEntry>&) {
    // report.html's temporary on a device that is always full.
    std::filesystem::create_symlink("/dev/full", session_dir + "/report.html.tmp");
    report::writeSessionReport(session_dir);
  };
  SessionManager manager(backend, settings);
  EventLog log;
  manager.setEventSink(log.sink());
  const std::string id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-5"));
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  EXPECT_NE(end.message.find("result.json is written, but the report (summary.txt, report.html) "
                             "is not: "),
            std::string::npos)
      << end.message;
  EXPECT_NE(end.message.find("No space left on device"), std::string::npos) << end.message;
  EXPECT_NE(end.message.find("zerocal report " + dir.path + "/" + id), std::string::npos)
      << end.message;
  const auto results = log.of<ResultEvent>();
  ASSERT_EQ(results.size(), 1u);
  EXPECT_NE(results[0].report_error.find("report.html.tmp: cannot write: No space left on device"),
            std::string::npos)
      << results[0].report_error;
  const auto states = log.of<StateEvent>();
  ASSERT_FALSE(states.empty());
  EXPECT_EQ(states.back().state, SessionState::kDone);
  EXPECT_EQ(states.back().message, end.message);
  const std::filesystem::path folder(dir.path + "/" + id);
  EXPECT_TRUE(std::filesystem::exists(folder / "result.json"));
  EXPECT_FALSE(std::filesystem::exists(folder / "report.html"));
  EXPECT_FALSE(
      std::filesystem::exists(std::filesystem::symlink_status(folder / "report.html.tmp")));
}

// A pose that does not fit the others: the solve names it, the run measures it again (both lines
// stay in the journal) and the result rests on the new measurement. Stray light strikes pose 2
// once (the world's forced gross error; the run's move ends at pose 2's planned joints, as the
// spot is aimed at from the third pose on); measured again, it fits.
TEST(SessionManager, APoseTheSolveNamesIsMeasuredAgainAndBothMeasurementsStayInTheJournal) {
  const TempDir dir;
  sim::SimulatedCellOptions cell = cellFor(5);
  cell.world.gross.forced_at_deg = testing::storedPlan("ideal-5-10-poses")[1].q_deg;
  cell.world.gross.forced_kind = GrossErrors::Kind::kStrayLight;
  sim::SimBackend backend(cell);
  SessionManager manager(backend, settingsIn(dir.path));
  EventLog log;
  manager.setEventSink(log.sink());
  const std::string id =
      manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-5-10-poses"));
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  const nlohmann::json result = toJson(manager.result(id));
  const nlohmann::json remeasured = result["remeasured"];
  ASSERT_EQ(remeasured.size(), 1u) << remeasured.dump();
  EXPECT_EQ(remeasured[0], 2);
  ASSERT_EQ(log.of<RemeasureEvent>().size(), 1u);
  EXPECT_EQ(nlohmann::json(log.of<RemeasureEvent>()[0].poses), remeasured);

  const JournalContents journal = readJournal(dir.path + "/" + id + "/journal.jsonl");
  ASSERT_EQ(journal.records.size(), 10u + remeasured.size());
  for (std::size_t k = 0; k < remeasured.size(); ++k) {
    const PoseRecord& again = journal.records[10 + k];
    const int pose = remeasured[k].get<int>();
    EXPECT_EQ(again.remeasure_of, pose - 1);
    // The first measurement is still there, and the new one is a measurement of its own.
    const PoseRecord& first = journal.records[pose - 1];
    EXPECT_EQ(first.remeasure_of, -1);
    EXPECT_NE(first.recorded_ns, again.recorded_ns);
  }
  // The solve rests on 10 poses (each plan pose's latest measurement). Whether the new reading
  // fits follows the noise draws too, so it is not asserted here; the gross-error experiment
  // measures it (docs/results.md).
  EXPECT_EQ(result["poses"], 10);
  for (int k = 0; k < kOffsetCount; ++k) {
    const std::string name = unknownName(k);
    EXPECT_NEAR(result["parameters"][name]["value"].get<double>(),
                result["truth"][name].get<double>(),
                4 * result["parameters"][name]["sigma"].get<double>())
        << name;
  }
  // A technician's terminal says so: the poses measured again are marked in the breakdown.
  int again_entries = 0;
  for (const auto& pose : result["pose_breakdown"]) again_entries += pose.value("again", false);
  EXPECT_EQ(again_entries, static_cast<int>(remeasured.size()));
}

TEST(SessionManager, OneSessionAtATimeAndAbortStopsIt) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(6));
  SessionManager manager(backend, settingsIn(dir.path));
  const std::string id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-6"));
  try {
    manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-6"));
    FAIL() << "a second start was accepted";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "busy");
    EXPECT_NE(std::string(e.what()).find(id), std::string::npos) << e.what();
  }
  EXPECT_TRUE(manager.abort());
  const SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.state, SessionState::kAborted);
  EXPECT_LT(end.recorded, 8);
  EXPECT_FALSE(manager.abort());  // nothing left to abort
  EXPECT_THROW(toJson(manager.result(id)), Refused);
}

// An abort while `start` is still planning (about a second) is for the session being started:
// it ends aborted before it connects, nothing moved; the previous session is not touched.
TEST(SessionManager, AbortWhileStartIsPlanningAbortsTheNewSessionBeforeAnyMove) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(7));
  SessionManager manager(backend, settingsIn(dir.path));
  auto started =
      std::async(std::launch::async, [&] { return manager.start(manager.defaultRequest()); });
  bool aborted = false;
  while (!aborted && started.wait_for(std::chrono::milliseconds(0)) != std::future_status::ready)
    aborted = manager.abort();
  ASSERT_TRUE(aborted) << "start answered before an abort landed";
  const std::string id = started.get();
  const SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.session_id, id);
  EXPECT_EQ(end.state, SessionState::kAborted) << end.message;
  EXPECT_EQ(end.recorded, 0);
  const std::string journal = dir.path + "/" + id + "/journal.jsonl";
  EXPECT_TRUE(!std::filesystem::exists(journal) || std::filesystem::file_size(journal) == 0);
}

TEST(SessionManager, AnAbortedSessionResumesWithoutLosingOrRepeatingAPose) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(7));
  SessionManager manager(backend, settingsIn(dir.path));
  EventLog log;
  // Abort from the event thread as soon as the third pose is on disk, once: after the resume a
  // second measurement of pose 3 (the solve may name it) is not another cue.
  bool aborted = false;
  log.also = [&manager, &aborted](const SessionEvent& e) {
    if (recordedPose(e) == 3 && !aborted) {
      aborted = true;
      manager.abort();
    }
  };
  manager.setEventSink(log.sink());
  const std::string id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-7"));
  SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kAborted);
  ASSERT_EQ(end.recorded, 3);
  ASSERT_EQ(manager.sessions().size(), 1u);
  EXPECT_FALSE(manager.sessions()[0].finished);

  EXPECT_EQ(manager.resume({}), id);  // the latest unfinished one
  end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  EXPECT_EQ(end.resumed_from, 3);
  // Each plan pose once, in order; after them only second measurements of poses the solve named.
  const std::vector<PoseRecord> lines = readJournal(dir.path + "/" + id + "/journal.jsonl").records;
  ASSERT_GE(lines.size(), 8u);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    EXPECT_EQ(lines[i].index, static_cast<int>(i));
    EXPECT_EQ(lines[i].remeasure_of >= 0, i >= 8) << i;
  }
  EXPECT_EQ(lines.size() - 8, toJson(manager.result(id))["remeasured"].size());
  EXPECT_EQ(toJson(manager.result(id))["resumed_from"], 3);
  try {
    manager.resume({id});
    FAIL() << "a finished session was resumed";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "finished");
  }
}

// Waits until the session waits for the PSD to be moved or is no longer active; its status.
SessionStatus untilWaitingOrEnded(const SessionManager& manager) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(3);
  for (;;) {
    const SessionStatus s = manager.status();
    if (s.state == SessionState::kAwaitingPlacement || !isActive(s.state) ||
        std::chrono::steady_clock::now() > deadline)
      return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

std::string refusalOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Refused& e) {
    return e.code();
  }
  return "accepted";
}

// Two PSD placements of 8 poses (tests/data/plans/ideal-5-2-placements): the session waits after
// the first placement's last pose, says where the PSD goes, and only a continue moves it on; the
// simulated PSD moves when continued, and the result is the several-placement solve's.
TEST(SessionManagerPlacements, WaitsForThePsdAtEachPlacementAndSolvesWithEveryPlacement) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(5));
  SessionManager manager(backend, settingsIn(dir.path));
  EventLog log;
  manager.setEventSink(log.sink());
  EXPECT_EQ(refusalOf([&] { manager.continueSession({}); }), "not_waiting");  // nothing waits

  const std::string id =
      manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-5-2-placements"));
  const SessionFile session = SessionStore(dir.path).readSession(id);
  ASSERT_EQ(session.placement_centres_mm.size(), 2u);
  EXPECT_EQ(session.placement_centres_mm[0], session.target_mm);

  SessionStatus waiting = untilWaitingOrEnded(manager);
  ASSERT_EQ(waiting.state, SessionState::kAwaitingPlacement) << waiting.message;
  EXPECT_EQ(waiting.recorded, 8);  // every pose of placement 1, none of placement 2
  EXPECT_EQ(waiting.placement, 1);
  EXPECT_EQ(waiting.placement_count, 2);
  EXPECT_EQ(waiting.next_placement, 2);
  // The planned centre the plan's placement-2 poses aim at (where their nominal lines cross).
  EXPECT_LT((waiting.next_centre_mm - session.placement_centres_mm[1]).norm(), 1e-9);
  EXPECT_LT((waiting.next_centre_mm - Eigen::Vector3d(613.177, 652.763, 585.079)).norm(), 0.01);
  EXPECT_NE(waiting.message.find("placement 2 of 2"), std::string::npos) << waiting.message;
  EXPECT_NE(waiting.message.find("zerocal continue"), std::string::npos) << waiting.message;
  const auto placed = log.atLeast<PlacementEvent>(1);
  ASSERT_EQ(placed.size(), 1u);
  EXPECT_EQ(placed[0].placement, 2);
  EXPECT_EQ(placed[0].centre_mm, waiting.next_centre_mm);
  EXPECT_EQ(backend.cell().world().active_placement, 1);  // not moved before the continue
  // The technician placing the PSD may read it: a reading is taken now, not the session's last.
  std::promise<std::optional<LiveReading>> now;
  manager.readPsd([&now](std::optional<LiveReading> r, const std::string&) { now.set_value(r); });
  const std::optional<LiveReading> reading = now.get_future().get();
  ASSERT_TRUE(reading);
  EXPECT_FALSE(reading->during_session);
  // Still one session at a time while it waits.
  EXPECT_EQ(refusalOf([&] { manager.start(manager.defaultRequest()); }), "busy");
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(manager.status().state, SessionState::kAwaitingPlacement);  // nothing moves meanwhile
  EXPECT_EQ(manager.status().recorded, 8);

  EXPECT_EQ(manager.continueSession({}), id);
  EXPECT_EQ(refusalOf([&] { manager.continueSession({}); }), "not_waiting");
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  EXPECT_EQ(end.placement, 2);

  // The simulated PSD moved to placement 2's truth: off its planned centre by as much as the
  // world's own is off its taught centre, and the truth file says where.
  const World& world = backend.cell().world();
  EXPECT_EQ(world.active_placement, 2);
  ASSERT_EQ(world.placements.size(), 1u);
  const double off_mm = (world.psd_centre_taught_mm - world.psd_position_mm).norm();
  EXPECT_NEAR((world.placements[0].position_mm - waiting.next_centre_mm).norm(), off_mm, 1e-9);
  const World truth = loadWorld(dir.path + "/" + id + "/truth-world.yaml");
  ASSERT_EQ(truth.placements.size(), 1u);
  EXPECT_LT((truth.placements[0].position_mm - world.placements[0].position_mm).norm(), 1e-9);

  // The journal: placement 1's poses, the move of the PSD, placement 2's poses.
  const JournalContents journal = readJournal(dir.path + "/" + id + "/journal.jsonl");
  ASSERT_EQ(journal.placements.size(), 1u);
  EXPECT_EQ(journal.placements[0].first_index, 8);
  EXPECT_EQ(Eigen::Vector3d(journal.placements[0].centre_mm.data()), waiting.next_centre_mm);
  ASSERT_GE(journal.records.size(), 16u);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(journal.records[i].placement, i < 8 ? 1 : 2) << i;

  // result.json: each placement's centre, the link errors identified or not with the reason,
  // and offsets near the truth.
  const nlohmann::json result = toJson(manager.result(id));
  ASSERT_EQ(result["placements"].size(), 2u);
  EXPECT_EQ(result["placements"][1]["placement"], 2);
  EXPECT_EQ(result["placements"][1]["poses"], 8);
  const Eigen::Vector3d centre2(result["placements"][1]["target_mm"][0].get<double>(),
                                result["placements"][1]["target_mm"][1].get<double>(),
                                result["placements"][1]["target_mm"][2].get<double>());
  // The PSD found where it stands, as the controller's joint 1 sees it: turned by delta1, which
  // no measurement at the PSD determines.
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(-world.true_offsets_deg[0] * kDegToRad, Eigen::Vector3d::UnitZ())
          .toRotationMatrix();
  EXPECT_LT((centre2 - turn * world.placements[0].position_mm).norm(), 0.5)
      << centre2.transpose() << " against " << (turn * world.placements[0].position_mm).transpose();
  int links_identified = 0, links_named = 0;
  for (int l = 0; l < kLinkParameterCount; ++l) {
    const nlohmann::json& p = result["parameters"].at(linkParamName(l));
    links_identified += p["identifiable"].get<bool>() ? 1 : 0;
  }
  for (const auto& n : result["not_identifiable"])
    if (n["name"].get<std::string>().rfind("d", 0) == 0 &&
        n["name"].get<std::string>().find("delta") == std::string::npos) {
      ++links_named;
      EXPECT_FALSE(n["reason"].get<std::string>().empty());
    }
  EXPECT_GE(links_identified, 10);
  EXPECT_EQ(links_identified + links_named, kLinkParameterCount);
  EXPECT_GT(result["rank"].get<int>(), kIdentifiedCount);
  ASSERT_TRUE(result.contains("truth"));
  for (int k = 0; k < kOffsetCount; ++k) {
    const nlohmann::json& p = result["parameters"][unknownName(k)];
    ASSERT_TRUE(p["identifiable"].get<bool>()) << unknownName(k);
    const double error = p["value"].get<double>() - result["truth"][unknownName(k)].get<double>();
    EXPECT_LT(std::abs(error), 4 * p["sigma"].get<double>())
        << unknownName(k) << " error " << error << " sigma " << p["sigma"];
  }
}

// Aborted while waiting, the session ends at once (no worker runs it); resumed, or resumed by a
// daemon restarted meanwhile, it waits again for the PSD rather than measuring placement 2's
// poses with the PSD at placement 1; a continue then finishes it.
TEST(SessionManagerPlacements, AbortedOrRestartedWhileWaitingItWaitsAgainOnResume) {
  const TempDir dir;
  std::string id;
  {
    sim::SimBackend backend(cellFor(5));
    SessionManager manager(backend, settingsIn(dir.path));
    id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-5-2-placements"));
    ASSERT_EQ(untilWaitingOrEnded(manager).state, SessionState::kAwaitingPlacement);
    EXPECT_TRUE(manager.abort());
    const SessionStatus aborted = manager.status();
    EXPECT_EQ(aborted.state, SessionState::kAborted);
    EXPECT_NE(aborted.message.find("placement 2"), std::string::npos) << aborted.message;
    EXPECT_EQ(refusalOf([&] { manager.continueSession({}); }), "not_waiting");
    EXPECT_FALSE(manager.abort());  // nothing runs now

    EXPECT_EQ(manager.resume({id}), id);
    const SessionStatus again = untilWaitingOrEnded(manager);
    ASSERT_EQ(again.state, SessionState::kAwaitingPlacement) << again.message;
    EXPECT_EQ(again.recorded, 8);
    EXPECT_EQ(again.resumed_from, 8);
    EXPECT_EQ(again.next_placement, 2);
    // The daemon is killed while it waits: the manager and the cell go, the folder stays.
  }
  sim::SimBackend backend(cellFor(5));
  SessionManager manager(backend, settingsIn(dir.path));
  EventLog log;
  manager.setEventSink(log.sink());
  EXPECT_EQ(refusalOf([&] { manager.continueSession({}); }), "not_waiting");  // not resumed yet
  EXPECT_EQ(manager.resume({}), id);
  const SessionStatus waiting = untilWaitingOrEnded(manager);
  ASSERT_EQ(waiting.state, SessionState::kAwaitingPlacement) << waiting.message;
  EXPECT_EQ(waiting.recorded, 8);
  EXPECT_TRUE(log.of<PoseEvent>().empty());  // nothing measured with the PSD where it was
  // Taught 2 mm off the planned centre: the servo's search finds the spot all the same.
  const Eigen::Vector3d taught = waiting.next_centre_mm + Eigen::Vector3d(2, 0, 0);
  ContinueRequest request;
  request.centre_mm = taught;
  EXPECT_EQ(manager.continueSession(request), id);
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  const JournalContents journal = readJournal(dir.path + "/" + id + "/journal.jsonl");
  ASSERT_EQ(journal.placements.size(), 1u);
  EXPECT_EQ(Eigen::Vector3d(journal.placements[0].centre_mm.data()), taught);
  EXPECT_EQ(toJson(manager.result(id))["placements"].size(), 2u);
}

TEST(SessionManagerPlacements,
     PlacementsAreRefusedOutsideTheirRangeAndOnACellThatCannotMoveThePsd) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(5));
  SessionManager manager(backend, settingsIn(dir.path));
  StartRequest request = manager.defaultRequest();
  EXPECT_EQ(request.placements, 1);
  request.placements = kMaxDefaultPlacements + 1;
  EXPECT_EQ(refusalOf([&] { manager.preview(request); }), "bad_request");
  request.placements = 0;
  EXPECT_EQ(refusalOf([&] { manager.start(request); }), "bad_request");
  EXPECT_TRUE(manager.sessions().empty());
}

TEST(SessionManager, APlanThatCannotIdentifyEveryOffsetIsRefusedBeforeAnything) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(8));
  SessionManager manager(backend, settingsIn(dir.path));
  // Pattern II with joint 1 held: delta2 trades against the target (docs/maths.md).
  PlanOptions options;
  options.pattern = Pattern::kII;
  options.joint1_fixed = true;
  options.psd_normal = backend.knowledge().cell.psd_rotation.col(2);
  const Plan weak =
      planPoses(backend.knowledge().cell, backend.knowledge().taught_centre_mm, options);
  const std::string plan_file = dir.path + "/weak.csv";
  std::ofstream(plan_file) << formatJointSet(weak.poses);
  StartRequest request = manager.defaultRequest();
  request.plan = PlanKind::kFile;
  request.plan_file = plan_file;
  try {
    manager.start(request);
    FAIL() << "pattern II was accepted";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "not_identifiable");
    EXPECT_NE(std::string(e.what()).find("delta"), std::string::npos) << e.what();
  }
  EXPECT_EQ(manager.status().state, SessionState::kIdle);
  EXPECT_TRUE(manager.sessions().empty());
  // The preview shows the same without refusing.
  const Plan preview = manager.preview(request);
  EXPECT_FALSE(preview.prediction.identifiable[0]);
  request.plan_file = dir.path + "/missing.csv";
  EXPECT_THROW(manager.preview(request), Refused);
  request.plan = PlanKind::kOptimal;
  request.poses = 2;
  EXPECT_THROW(manager.preview(request), Refused);
}

// A plan file of 0 to 5 poses (a header alone crashed the daemon) is refused before anything,
// every time, by start and by the preview alike: the same minimum as a solve.
TEST(SessionManager, APlanFileWithTooFewPosesIsRefusedEveryTimeAndNothingMoves) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(8));
  SessionManager manager(backend, settingsIn(dir.path));
  const std::vector<Pose> good = testing::storedPlan("ideal-8");  // the optimal planner's
  StartRequest request = manager.defaultRequest();
  request.plan = PlanKind::kFile;
  request.plan_file = dir.path + "/few.csv";
  for (int count = 0; count < kMinimumPoses; ++count) {
    std::ofstream(request.plan_file) << formatJointSet({good.begin(), good.begin() + count});
    for (int repeat = 0; repeat < 3; ++repeat) {
      try {
        manager.start(request);
        FAIL() << count << " poses were accepted";
      } catch (const Refused& e) {
        EXPECT_EQ(e.code(), "bad_request") << count << " poses: " << e.what();
        EXPECT_NE(std::string(e.what()).find("at least 6"), std::string::npos) << e.what();
      }
      EXPECT_THROW(manager.preview(request), Refused);
    }
  }
  EXPECT_EQ(manager.status().state, SessionState::kIdle);
  EXPECT_TRUE(manager.sessions().empty());
}

// The servo and the controller keep controller.irc5.limit_margin_deg from each joint limit: a plan
// file with a pose inside that margin is refused at start (and by the preview) before anything
// moves, naming the pose, the joint, its value and the limit; a session whose plan lies inside the
// margin configured when it is resumed is refused the same way.
TEST(SessionManager, APlanPoseInsideTheJointLimitMarginIsRefusedBeforeAnythingMoves) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(8));
  const Robot robot = backend.knowledge().cell.robot;
  std::vector<Pose> plan = testing::storedPlan("ideal-8");
  {
    ManagerSettings settings = settingsIn(dir.path);
    ASSERT_EQ(settings.run.servo.limit_margin_deg, 1.0);
    SessionManager manager(backend, settings);
    std::vector<Pose> near = plan;
    near[2].q_deg[4] = robot.limits[4].upper_deg - 0.5;  // within the limit, inside the margin
    StartRequest request = manager.defaultRequest();
    request.plan = PlanKind::kFile;
    request.plan_file = dir.path + "/near-limit.csv";
    std::ofstream(request.plan_file) << formatJointSet(near);
    for (const bool preview : {false, true}) {
      try {
        if (preview)
          manager.preview(request);
        else
          manager.start(request);
        FAIL() << "a pose inside the margin was accepted";
      } catch (const Refused& e) {
        EXPECT_EQ(e.code(), "out_of_limits") << e.what();
        const std::string why = e.what();
        EXPECT_NE(why.find("pose 3 (line "), std::string::npos) << why;
        EXPECT_NE(why.find(fmt::format("joint 5 = {} deg is outside", near[2].q_deg[4])),
                  std::string::npos)
            << why;
        EXPECT_NE(why.find(fmt::format("{}] deg (limits less a 1 deg margin)",
                                       robot.limits[4].upper_deg - 1.0)),
                  std::string::npos)
            << why;
        EXPECT_NE(why.find("nothing moved"), std::string::npos) << why;
      }
    }
    EXPECT_EQ(manager.status().state, SessionState::kIdle);
    EXPECT_TRUE(manager.sessions().empty());
  }

  // A session of the stored plan, stopped at once; then the margin is configured wider than the
  // plan's closest approach to a limit.
  std::string id;
  {
    SessionManager manager(backend, settingsIn(dir.path));
    id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-8"));
    manager.abort();
    ASSERT_EQ(manager.waitIdle().state, SessionState::kAborted);
  }
  double closest = 1e9;
  for (const Pose& p : plan)
    for (int j = 0; j < kJointCount; ++j)
      closest = std::min({closest, p.q_deg[j] - robot.limits[j].lower_deg,
                          robot.limits[j].upper_deg - p.q_deg[j]});
  ManagerSettings wider = settingsIn(dir.path);
  wider.run.servo.limit_margin_deg = closest + 0.5;
  SessionManager manager(backend, wider);
  try {
    manager.resume({id});
    FAIL() << "a plan inside the margin was resumed";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "out_of_limits") << e.what();
    EXPECT_NE(std::string(e.what()).find("session " + id + " cannot be resumed: pose "),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("limits less a"), std::string::npos) << e.what();
  }
  EXPECT_EQ(manager.status().state, SessionState::kIdle);
  EXPECT_FALSE(manager.sessions().at(0).finished);
}

// A plan whose first pose points the laser far off the detector, as a fixture or a cable in the
// beam would: the spot is never found there (no pose yet to predict it from). The optimal plan
// of `count` poses for the world of seed 5 (stored), its first pose turned away.
StartRequest planWithABlindFirstPose(SessionManager& manager, const std::string& dir, int count) {
  std::vector<Pose> plan = testing::storedPlan("ideal-5-" + std::to_string(count) + "-poses");
  plan[0].q_deg[0] += 20.0;  // some 300 mm off at the PSD, far beyond the search
  StartRequest request = manager.defaultRequest();
  request.plan = PlanKind::kFile;
  request.plan_file = dir + "/blind.csv";
  std::ofstream(request.plan_file) << formatJointSet(plan);
  return request;
}

// A pose whose spot is never found faults the session on every resume; the technician may skip
// it, journalled, when the plan still identifies every offset without it.
TEST(SessionManager, APoseWhoseSpotIsNeverFoundIsSkippedOnRequestWhenThePlanDoesWithoutIt) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(5));
  SessionManager manager(backend, settingsIn(dir.path));
  EventLog log;
  manager.setEventSink(log.sink());
  const std::string id = manager.start(planWithABlindFirstPose(manager, dir.path, 10));
  SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kFaulted) << end.message;
  EXPECT_EQ(end.recorded, 0);
  EXPECT_NE(end.message.find("spot not found"), std::string::npos) << end.message;
  EXPECT_NE(end.message.find("zerocal resume " + id + " --skip-pose 1"), std::string::npos)
      << end.message;
  EXPECT_EQ(end.skippable_pose, 1);

  // Resumed as it is, the pose fails again: nothing is skipped without being asked.
  manager.resume({id});
  end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kFaulted) << end.message;
  EXPECT_EQ(end.skippable_pose, 1);
  EXPECT_TRUE(journalIndices(dir.path + "/" + id + "/journal.jsonl").empty());

  // Only the next pose may be skipped.
  for (int wrong : {2, 10, 11}) {
    try {
      manager.resume({id, wrong});
      FAIL() << "pose " << wrong << " was skipped";
    } catch (const Refused& e) {
      EXPECT_EQ(e.code(), "bad_request") << e.what();
    }
  }
  EXPECT_EQ(manager.status().state, SessionState::kFaulted);

  EXPECT_EQ(manager.resume({id, 1}), id);
  end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kDone) << end.message;
  EXPECT_EQ(end.recorded, 10);
  EXPECT_EQ(end.skippable_pose, 0);
  EXPECT_EQ(journalIndices(dir.path + "/" + id + "/journal.jsonl"),
            (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));
  const JournalContents journal = readJournal(dir.path + "/" + id + "/journal.jsonl");
  ASSERT_EQ(journal.records.size(), 10u);
  EXPECT_FALSE(journal.records[0].measured());
  // The reason on disk names the fault that made the technician skip it.
  EXPECT_NE(journal.records[0].skipped.find("spot not found"), std::string::npos)
      << journal.records[0].skipped;
  for (std::size_t i = 1; i < journal.records.size(); ++i)
    EXPECT_TRUE(journal.records[i].measured());

  const nlohmann::json result = toJson(manager.result(id));
  EXPECT_EQ(result["poses"], 9);  // the solve rests on the measured poses only
  ASSERT_EQ(result["pose_breakdown"].size(), 10u);
  EXPECT_TRUE(result["pose_breakdown"][0].contains("skipped"));
  EXPECT_FALSE(result["pose_breakdown"][1].contains("skipped"));
  for (int k = 0; k < kOffsetCount; ++k)  // the ideal world: the truth within a few sigma
    EXPECT_NEAR(result["parameters"][unknownName(k)]["value"].get<double>(),
                result["truth"][unknownName(k)].get<double>(),
                5 * result["parameters"][unknownName(k)]["sigma"].get<double>() + 1e-4)
        << unknownName(k);
  bool skip_event = false;
  for (const auto& e : log.of<PoseEvent>())
    skip_event |= !e.record.measured() && e.record.planIndex() == 0;
  EXPECT_TRUE(skip_event);
  ASSERT_EQ(manager.sessions().size(), 1u);
  EXPECT_EQ(manager.sessions()[0].skipped_poses, 1);
}

// With 6 poses, none can go: the fault says so, and a skip is refused with nothing written.
TEST(SessionManager, APoseThePlanCannotDoWithoutIsNotSkipped) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(5));
  SessionManager manager(backend, settingsIn(dir.path));
  const std::string id = manager.start(planWithABlindFirstPose(manager, dir.path, 6));
  const SessionStatus end = manager.waitIdle();
  ASSERT_EQ(end.state, SessionState::kFaulted) << end.message;
  EXPECT_EQ(end.skippable_pose, 0);
  EXPECT_NE(end.message.find("plan a new session"), std::string::npos) << end.message;
  try {
    manager.resume({id, 1});
    FAIL() << "a pose of a 6-pose plan was skipped";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "not_identifiable") << e.what();
    EXPECT_NE(std::string(e.what()).find("without pose 1"), std::string::npos) << e.what();
  }
  EXPECT_EQ(manager.status().state, SessionState::kFaulted);
  EXPECT_TRUE(journalIndices(dir.path + "/" + id + "/journal.jsonl").empty());
}

// A garbled line in one old session's journal must neither fail the listing nor stop another
// session from being resumed; the damaged one is named and refused.
TEST(SessionManager, ADamagedJournalIsReportedAndSkippedNeverFatalToTheOthers) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(12));
  std::string healthy, damaged;
  {
    SessionManager manager(backend, settingsIn(dir.path));
    // Two sessions aborted after their first recorded pose.
    for (std::string* id : {&healthy, &damaged}) {  // the damaged one is the newest
      EventLog log;
      std::promise<void> recorded;
      bool once = false;
      log.also = [&](const SessionEvent& e) {
        if (recordedPose(e) > 0 && !once) {
          once = true;
          manager.abort();
          recorded.set_value();
        }
      };
      manager.setEventSink(log.sink());
      *id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-12"));
      ASSERT_EQ(recorded.get_future().wait_for(std::chrono::seconds(120)),
                std::future_status::ready);
      manager.waitIdle();
    }
    manager.setEventSink(nullptr);
  }
  // Duplicate the first line and add a good-looking last one: a bad line before the last.
  const std::string journal = dir.path + "/" + damaged + "/journal.jsonl";
  std::string first;
  std::getline(std::ifstream(journal), first);
  std::ofstream(journal, std::ios::app) << first << "\n" << first << "\n";

  SessionManager manager(backend, settingsIn(dir.path));
  const std::vector<SessionInfo> listed = manager.sessions();
  ASSERT_EQ(listed.size(), 2u);
  for (const SessionInfo& s : listed) {
    if (s.id == damaged)
      EXPECT_NE(s.damaged.find("journal.jsonl:2"), std::string::npos) << s.damaged;
    else
      EXPECT_TRUE(s.damaged.empty()) << s.damaged;
  }
  try {
    manager.resume({damaged});
    FAIL() << "a damaged session was resumed";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "damaged");
  }
  // The latest resumable session is the healthy one, whichever is newer.
  EXPECT_EQ(manager.resume({}), healthy);
  const SessionStatus done = manager.waitIdle();
  EXPECT_EQ(done.state, SessionState::kDone) << done.message;
  EXPECT_TRUE(toJson(manager.result(healthy)).contains("parameters"));
  EXPECT_TRUE(toJson(manager.result("")).contains("parameters"));
}

TEST(SessionManager, IdsThatAreNotSessionIdsAndUnknownSessionsAreRefused) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(9));
  SessionManager manager(backend, settingsIn(dir.path));
  EXPECT_EQ(refusalOf([&] { toJson(manager.result("../../etc")); }), "bad_request");
  EXPECT_EQ(refusalOf([&] { manager.resume({"/tmp"}); }), "bad_request");
  EXPECT_EQ(refusalOf([&] { toJson(manager.result("20200101T000000Z")); }), "not_found");
  EXPECT_EQ(refusalOf([&] { manager.resume({"20200101T000000Z"}); }), "not_found");
  EXPECT_EQ(refusalOf([&] { manager.resume({}); }), "not_found");
  EXPECT_EQ(refusalOf([&] { toJson(manager.result("")); }), "not_found");
}

TEST(SessionManager, ReadsThePsdWhenIdleAndReportsTheSessionsLatestReadingDuringOne) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(10));
  SessionManager manager(backend, settingsIn(dir.path));
  std::promise<std::pair<std::optional<LiveReading>, std::string>> idle;
  manager.readPsd([&idle](std::optional<LiveReading> r, const std::string& error) {
    idle.set_value({r, error});
  });
  const auto [reading, error] = idle.get_future().get();
  ASSERT_TRUE(reading) << error;
  EXPECT_FALSE(reading->during_session);

  std::promise<std::optional<LiveReading>> during;
  EventLog log;
  log.also = [&](const SessionEvent& e) {
    if (recordedPose(e) == 2)
      manager.readPsd(
          [&during](std::optional<LiveReading> r, const std::string&) { during.set_value(r); });
  };
  manager.setEventSink(log.sink());
  manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-10"));
  const std::optional<LiveReading> live = during.get_future().get();
  ASSERT_TRUE(live);
  EXPECT_TRUE(live->during_session);
  EXPECT_TRUE(live->reading.spot_present);  // the servo just recorded it on the detector
  EXPECT_LT(std::hypot(live->reading.spot.u_mm, live->reading.spot.v_mm), 1.0);
  manager.abort();
  manager.waitIdle();
}

TEST(SessionManager, DestroyedMidSessionItStopsCleanlyWithEveryRecordedPoseOnDisk) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(11));
  std::string id;
  std::promise<void> two_recorded;
  {
    SessionManager manager(backend, settingsIn(dir.path));
    EventLog log;
    log.also = [&](const SessionEvent& e) {
      if (recordedPose(e) == 2) two_recorded.set_value();
    };
    manager.setEventSink(log.sink());
    id = manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-11"));
    // A session that ends before its second pose fails here instead of waiting forever.
    ASSERT_EQ(two_recorded.get_future().wait_for(std::chrono::seconds(120)),
              std::future_status::ready)
        << "pose 2 never recorded: " << manager.status().message;
  }  // as on SIGTERM: the destructor aborts, stops the robot and joins the worker
  const std::vector<int> indices = journalIndices(dir.path + "/" + id + "/journal.jsonl");
  ASSERT_GE(indices.size(), 2u);
  for (std::size_t i = 0; i < indices.size(); ++i) EXPECT_EQ(indices[i], static_cast<int>(i));
  EXPECT_FALSE(std::filesystem::exists(dir.path + "/" + id + "/result.json"));
}

class UnreachableBackend final : public CellBackend {
 public:
  explicit UnreachableBackend(CellKnowledge k) : k_(std::move(k)) {}
  const char* name() const override { return "hardware"; }
  CellKnowledge knowledge() const override { return k_; }
  std::unique_ptr<ConnectedCell> connect() override {
    throw Error("cannot connect to 192.0.2.1:5000: connection refused");
  }

 private:
  CellKnowledge k_;
};

TEST(SessionManager, ACellThatCannotBeReachedFaultsTheSessionWithTheReason) {
  const TempDir dir;
  sim::SimBackend sim_backend(cellFor(12));
  UnreachableBackend backend(sim_backend.knowledge());
  SessionManager manager(backend, settingsIn(dir.path));
  manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-12"));
  const SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.state, SessionState::kFaulted);
  EXPECT_NE(end.message.find("connection refused"), std::string::npos) << end.message;
  EXPECT_EQ(end.recorded, 0);
  std::promise<std::string> error;
  manager.readPsd(
      [&error](std::optional<LiveReading>, const std::string& e) { error.set_value(e); });
  EXPECT_NE(error.get_future().get().find("connection refused"), std::string::npos);
}

// A cell whose connect() hangs until released, as a wedged driver would.
class HangingBackend final : public CellBackend {
 public:
  explicit HangingBackend(CellKnowledge k) : k_(std::move(k)) {}
  const char* name() const override { return "hardware"; }
  CellKnowledge knowledge() const override { return k_; }
  std::unique_ptr<ConnectedCell> connect() override {
    entered_.set_value();
    release_.get_future().wait();
    throw Error("released");
  }
  std::promise<void> entered_, release_;

 private:
  CellKnowledge k_;
};

TEST(SessionManager, TheWorkersStallShowsWhileItHangsAndIsZeroWhileItWaitsForWork) {
  const TempDir dir;
  sim::SimBackend sim_backend(cellFor(12));
  HangingBackend backend(sim_backend.knowledge());
  SessionManager manager(backend, settingsIn(dir.path));
  EXPECT_EQ(manager.workerStalledFor(), std::chrono::steady_clock::duration::zero());
  manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-12"));
  backend.entered_.get_future().wait();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_GE(manager.workerStalledFor(), std::chrono::milliseconds(90));
  backend.release_.set_value();
  EXPECT_EQ(manager.waitIdle().state, SessionState::kFaulted);
  EXPECT_EQ(manager.workerStalledFor(), std::chrono::steady_clock::duration::zero());
}

TEST(SessionManager, ASessionsProgressKeepsTheWorkersStallShort) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(12));
  SessionManager manager(backend, settingsIn(dir.path));
  std::atomic<bool> done{false};
  std::chrono::steady_clock::duration longest{};
  std::thread sampler([&] {
    while (!done) {
      longest = std::max(longest, manager.workerStalledFor());
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  manager.start(testing::onStoredPlan(manager.defaultRequest(), "ideal-12"));
  const SessionStatus end = manager.waitIdle();
  done = true;
  sampler.join();
  EXPECT_EQ(end.state, SessionState::kDone) << end.message;
  // Readings, phases and poses mark progress: far below the daemon's 120 s stall limit.
  EXPECT_LT(longest, std::chrono::seconds(10));
  EXPECT_EQ(manager.workerStalledFor(), std::chrono::steady_clock::duration::zero());
}

}  // namespace
}  // namespace zerocal::service

namespace zerocal::service {
namespace {

// The sim backend with the robot model's transmission of one joint given the wrong sign: what a
// wrong robot file does, the simulated arm keeping its true transmission.
class WrongSignBackend final : public CellBackend {
 public:
  WrongSignBackend(sim::SimulatedCellOptions options, int joint)
      : inner_(std::move(options)), joint_(joint) {}
  const char* name() const override { return inner_.name(); }
  CellKnowledge knowledge() const override {
    CellKnowledge k = inner_.knowledge();
    k.cell.robot.transmission[joint_ - 1] *= -1;
    return k;
  }
  std::unique_ptr<ConnectedCell> connect() override { return inner_.connect(); }
  sim::SimBackend& inner() { return inner_; }

 private:
  sim::SimBackend inner_;
  int joint_;
};

ManagerSettings applySettingsIn(const std::string& dir) {
  ManagerSettings s = settingsIn(dir);
  // The verification runs the configured plan: the stored one, not seconds of planning.
  s.session.plan = PlanKind::kFile;
  s.session.plan_file = testing::storedPlanPath("ideal-5");
  s.write_reports = [](const std::string& session_dir,
                       const std::vector<record::HistoryEntry>& history) {
    report::writeSessionReport(session_dir, history);
  };
  return s;
}

std::vector<nlohmann::json> applyLines(const std::string& path) {
  std::vector<nlohmann::json> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) lines.push_back(nlohmann::json::parse(line));
  return lines;
}

// The robot's record kept by the manager: the calibration recorded when its result is written,
// the apply and its verification when the apply ends; the same as the record rebuilt from the
// folders afterwards. Without a record, `robots` says so.
TEST(SessionManagerRecord, RecordsEachSessionWhenItsResultIsWrittenAndTheApplyWhenItEnds) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(6));
  record::SqliteRecord kept(dir.path + "/" + record::kRecordFileName);
  ManagerSettings settings = applySettingsIn(dir.path);
  settings.record = &kept;
  SessionManager manager(backend, std::move(settings));
  const std::string id = manager.start(manager.defaultRequest());
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  const std::vector<record::RobotSummary> robots = manager.robots();
  ASSERT_EQ(robots.size(), 1u);
  const ResultFile calibrated = manager.result(id);
  ASSERT_TRUE(calibrated.cell);
  EXPECT_EQ(robots[0].id.serial, calibrated.cell->controller.serial);
  std::vector<record::HistoryEntry> h = manager.history(robots[0].id);
  ASSERT_EQ(h.size(), 1u);
  EXPECT_EQ(h[0].session.session, id);
  ASSERT_TRUE(h[0].session.offsets[0]);
  EXPECT_EQ(h[0].session.offsets[0]->value_deg, calibrated.report.parameters[0].value);
  EXPECT_TRUE(h[0].events.empty());

  EXPECT_EQ(manager.apply({id, true}), id);
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  h = manager.history(robots[0].id);
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[1].session.kind, "verification");
  EXPECT_EQ(h[1].session.verifies, id);
  ASSERT_EQ(h[0].events.size(), 2u);
  EXPECT_EQ(h[0].events[0].kind, record::ControllerEventKind::kApply);
  EXPECT_EQ(h[0].events[0].outcome, "verified");
  EXPECT_EQ(h[0].events[0].before_rad, calibrated.cal_offset_rad);
  EXPECT_EQ(h[0].events[1].kind, record::ControllerEventKind::kVerification);
  EXPECT_EQ(h[0].events[1].outcome, "pass");
  EXPECT_EQ(h[0].events[1].verification, h[1].session.session);

  record::SqliteRecord rebuilt(dir.path + "/rebuilt.sqlite");
  rebuilt.rebuild(SessionStore(dir.path));
  EXPECT_EQ(rebuilt.history(robots[0].id), h);

  sim::SimBackend other(cellFor(6));
  const TempDir elsewhere;
  SessionManager without(other, applySettingsIn(elsewhere.path));
  try {
    without.robots();
    ADD_FAILURE() << "a manager without a record listed robots";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "no_record");
  }
}

// Calibrate, apply online, verify: the new zeros remove the world's offsets (the verification's
// simulated truth), the journal ends verified, and the status and events say so. Refused without
// the confirmation and while busy.
TEST(SessionManagerApply, AppliesVerifiesAndKeepsTheNewValues) {
  const TempDir dir;
  sim::SimBackend backend(cellFor(6));
  SessionManager manager(backend, applySettingsIn(dir.path));
  EventLog log;
  manager.setEventSink(log.sink());
  const std::string id = manager.start(manager.defaultRequest());
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  const ResultFile calibrated = manager.result(id);
  ASSERT_TRUE(calibrated.cal_offset_rad);
  const Joints shift_before = backend.cell().controller().zeroShiftDeg();

  try {
    manager.apply({id, false});
    ADD_FAILURE() << "applied without the confirmation";
  } catch (const Refused& e) {
    EXPECT_EQ(e.code(), "not_confirmed");
  }
  EXPECT_FALSE(std::filesystem::exists(dir.path + "/" + id + "/apply.jsonl"));
  EXPECT_EQ(manager.apply({id, true}), id);
  EXPECT_THROW(manager.start(manager.defaultRequest()), Refused);  // busy while it runs
  const SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.state, SessionState::kDone) << end.message;
  EXPECT_NE(end.apply.find("verified"), std::string::npos) << end.apply;

  const auto applied = log.of<ApplyEvent>();
  ASSERT_EQ(applied.size(), 1u);
  EXPECT_EQ(applied[0].outcome, ApplyOutcome::kVerified) << applied[0].message;
  ASSERT_EQ(applied[0].written_rad.size(), 6u);
  EXPECT_NE(applied[0].written_rad[2], applied[0].before_rad[2]);
  EXPECT_FALSE(log.of<ApplyProgressEvent>().empty());
  // The controller's zeros moved by the identified offsets, and the verification measured what
  // is left: near zero, as its simulated truth.
  const Joints shift = backend.cell().controller().zeroShiftDeg();
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(shift[k + 1] - shift_before[k + 1], -calibrated.report.parameters[k].value, 1e-3);
    EXPECT_LT(std::abs(applied[0].remaining_deg[k]), 0.02);
  }
  // The verification session says what it is for.
  const SessionFile verification_file = SessionStore(dir.path).readSession(applied[0].verification);
  EXPECT_EQ(verification_file.kind, SessionKind::kVerification);
  EXPECT_EQ(verification_file.verifies, id);
  // What is left on the arm is the calibration's own error, exactly.
  const ResultFile verification = manager.result(applied[0].verification);
  ASSERT_TRUE(verification.truth && calibrated.truth);
  for (int k = 0; k < 4; ++k)
    EXPECT_NEAR(verification.truth->offsets_deg[k],
                calibrated.truth->offsets_deg[k] - calibrated.report.parameters[k].value, 1e-5);
  const auto lines = applyLines(dir.path + "/" + id + "/apply.jsonl");
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines.front()["step"], "transmission_check");  // measured before the backup
  EXPECT_EQ(lines.front()["agree"], true);
  EXPECT_EQ(lines.back()["step"], "done");
  EXPECT_EQ(lines.back()["outcome"], "verified");
  // The session's summary is written again with the apply: values, verdict, warnings.
  std::ifstream in(dir.path + "/" + id + "/summary.txt");
  const std::string summary((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(summary.find("Applied to the controller"), std::string::npos) << summary;
  // ... and no longer says that nothing is written: entered again, they would be applied twice.
  EXPECT_EQ(summary.find("nothing is written to the controller"), std::string::npos) << summary;
  EXPECT_NE(summary.find("do not enter them again"), std::string::npos) << summary;
  EXPECT_NE(summary.find("Verified"), std::string::npos);
  EXPECT_NE(summary.find("Taught positions"), std::string::npos);
  EXPECT_NE(summary.find("cal_offset_3 = wrap("), std::string::npos);
  EXPECT_NE(summary.find("Transmissions measured"), std::string::npos) << summary;
  EXPECT_EQ(summary.find("DISAGREES"), std::string::npos) << summary;

  // A verification on its own afterwards: by default of the session applied last (not of the
  // verification session, the latest finished), judged, nothing written; the report keeps the
  // apply and adds the check.
  EXPECT_EQ(manager.verify({}), id);
  EXPECT_EQ(manager.waitIdle().state, SessionState::kDone);
  const auto checks = log.of<ApplyEvent>();
  ASSERT_EQ(checks.size(), 2u);
  EXPECT_EQ(checks[1].outcome, ApplyOutcome::kPassed) << checks[1].message;
  EXPECT_TRUE(checks[1].written_rad.empty());
  ASSERT_EQ(checks[1].before_rad.size(), 6u);
  for (int i = 0; i < 6; ++i)  // as the controller keeps them: float32
    EXPECT_NEAR(checks[1].before_rad[i], applied[0].written_rad[i], 2e-6) << i;
  std::ifstream again(dir.path + "/" + id + "/summary.txt");
  const std::string updated((std::istreambuf_iterator<char>(again)), {});
  EXPECT_NE(updated.find("Applied to the controller"), std::string::npos) << updated;
  EXPECT_NE(updated.find("Verified again later"), std::string::npos) << updated;

  // A verification alone that cannot complete (the controller answers every joint move with
  // garbage) leaves the verified calibration as it was: done, with the failure in the message,
  // not faulted; nothing was written.
  SimFaults garbled_moves;
  garbled_moves.garbage_code = 2;  // MoveAbsJ
  backend.cell().controller().setFaults(garbled_moves);
  const Joints shift_verified = backend.cell().controller().zeroShiftDeg();
  EXPECT_EQ(manager.verify({}), id);
  const SessionStatus failed = manager.waitIdle();
  EXPECT_EQ(failed.state, SessionState::kDone) << failed.message;
  EXPECT_EQ(failed.session_id, id);
  EXPECT_NE(failed.message.find("the verification did not complete"), std::string::npos)
      << failed.message;
  const auto third = log.of<ApplyEvent>();
  ASSERT_EQ(third.size(), 3u);
  EXPECT_EQ(third[2].outcome, ApplyOutcome::kFailed) << third[2].message;
  EXPECT_EQ(backend.cell().controller().zeroShiftDeg(), shift_verified);
}

// The joint (1-based) an awaiting_counter message asks the technician to update.
int counterJoint(const std::string& message) {
  const std::string key = "update joint ";
  const std::size_t at = message.find(key);
  return at == std::string::npos ? 0 : message[at + key.size()] - '0';
}

// Waits until the session is no longer applying: awaiting the technician, or ended.
SessionStatus untilTechnicianOrEnd(SessionManager& manager) {
  SessionStatus s = manager.status();
  for (int i = 0; i < 6000 && s.state == SessionState::kApplying; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    s = manager.status();
  }
  return s;
}

// A calibrated session on seed 6 (its apply crosses a seam) of a simulated cell that, as an IRC5
// over RAPID, cannot update a revolution counter remotely.
class CounterByTechnician : public ::testing::Test {
 protected:
  void SetUp() override {
    manager.setEventSink(log.sink());
    id = manager.start(manager.defaultRequest());
    ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  }
  static sim::SimulatedCellOptions cellWithoutRemoteUpdate() {
    sim::SimulatedCellOptions cell = cellFor(6);
    cell.remote_counter_update = false;
    return cell;
  }
  const TempDir dir;
  sim::SimBackend backend{cellWithoutRemoteUpdate()};
  SessionManager manager{backend, applySettingsIn(dir.path)};
  EventLog log;
  std::string id;
};

// An IRC5 over RAPID cannot update a revolution counter remotely. An apply whose new value crosses
// a joint's seam waits (awaiting_counter) for the technician to update the counter at the
// FlexPendant and continue; updated, the verification passes.
TEST_F(CounterByTechnician, ASeamCrossingWaitsForTheTechnicianToUpdateTheCounter) {
  EXPECT_EQ(manager.apply({id, true}), id);
  int waits = 0;
  for (SessionStatus s = untilTechnicianOrEnd(manager); s.state == SessionState::kAwaitingCounter;
       s = untilTechnicianOrEnd(manager)) {
    ++waits;
    const int joint = counterJoint(s.message);
    ASSERT_GE(joint, 2) << s.message;
    EXPECT_NE(s.message.find("zerocal continue"), std::string::npos) << s.message;
    // A centre is for a PSD placement, not for this wait.
    EXPECT_EQ(refusalOf([&] { manager.continueSession({Eigen::Vector3d(0, 0, 0)}); }),
              "bad_request");
    backend.cell().controller().updateRevolutionCounter(joint);  // the technician, at the mark
    EXPECT_EQ(manager.continueSession({}), id);
  }
  EXPECT_GE(waits, 1) << "seed 6 crosses no seam: the wait went untested";
  const SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.state, SessionState::kDone) << end.message;
  const auto applied = log.of<ApplyEvent>();
  ASSERT_EQ(applied.size(), 1u);
  EXPECT_EQ(applied[0].outcome, ApplyOutcome::kVerified) << applied[0].message;
  bool announced = false;
  for (const StateEvent& e : log.of<StateEvent>())
    announced |= e.state == SessionState::kAwaitingCounter;
  EXPECT_TRUE(announced);
}

// Aborted while it waits for the technician, the apply restores the values from before it.
TEST_F(CounterByTechnician, AnAbortWhileWaitingForTheTechnicianRollsTheApplyBack) {
  const Joints shift_before = backend.cell().controller().zeroShiftDeg();
  manager.apply({id, true});
  const SessionStatus waiting = untilTechnicianOrEnd(manager);
  ASSERT_EQ(waiting.state, SessionState::kAwaitingCounter) << waiting.message;
  EXPECT_TRUE(manager.abort());
  manager.waitIdle();
  const auto applied = log.of<ApplyEvent>();
  ASSERT_EQ(applied.size(), 1u);
  EXPECT_EQ(applied[0].outcome, ApplyOutcome::kRolledBack) << applied[0].message;
  // The values from before are back: the zeros where they were, but for the counter's turn,
  // which the technician must move back at the mark (the rollback says so).
  const Joints shift = backend.cell().controller().zeroShiftDeg();
  EXPECT_NE(applied[0].message.find("revolution counter"), std::string::npos) << applied[0].message;
  const int joint = counterJoint(waiting.message);
  for (int j = 2; j <= 5; ++j)
    if (j != joint) {
      EXPECT_NEAR(shift[j - 1], shift_before[j - 1], 1e-6) << "joint " << j;
    }
}

// A transmission sign wrong in the robot model would double delta3 on the arm: the apply measures
// the transmissions first and refuses, naming joint 3 with both ratios, before anything is
// written; the robot is back where it stood, the controller untouched, and the journal and the
// report show the measurement. (The rollback after a failed verification, for what a measurement
// cannot see, is tested on the engine: online_apply_test.cpp.)
TEST(SessionManagerApply, AWrongTransmissionSignIsRefusedBeforeAnyWrite) {
  const TempDir dir;
  WrongSignBackend backend(cellFor(6), 3);
  SessionManager manager(backend, applySettingsIn(dir.path));
  EventLog log;
  manager.setEventSink(log.sink());
  const std::string id = manager.start(manager.defaultRequest());
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  SimController& controller = backend.inner().cell().controller();
  const Joints shift_before = controller.zeroShiftDeg();
  const Joints joints_before = controller.commandedJoints();
  const std::array<double, 6> cal_before = controller.calOffsets();
  const long restarts_before = controller.restartCount();
  const long moves_before = controller.motionTotals().moves;
  manager.apply({id, true});
  const SessionStatus end = manager.waitIdle();
  EXPECT_EQ(end.state, SessionState::kFaulted);
  const auto applied = log.of<ApplyEvent>();
  ASSERT_EQ(applied.size(), 1u);
  EXPECT_EQ(applied[0].outcome, ApplyOutcome::kFailed);
  const std::string& why = applied[0].message;
  EXPECT_NE(why.find("joint 3: the robot file's transmission is -120, the cell measured +120.0"),
            std::string::npos)
      << why;
  EXPECT_NE(why.find("the sign is wrong"), std::string::npos) << why;
  EXPECT_NE(why.find("nothing was written"), std::string::npos) << why;
  EXPECT_EQ(why.find("joint 2"), std::string::npos) << why;  // the others agree
  // Nothing written, no restart, the zeros where they were, the robot back where it stood after
  // its eight small moves (four joints, out and back).
  EXPECT_EQ(controller.calOffsets(), cal_before);
  EXPECT_EQ(controller.restartCount(), restarts_before);
  EXPECT_EQ(controller.zeroShiftDeg(), shift_before);
  EXPECT_EQ(controller.commandedJoints(), joints_before);
  EXPECT_EQ(controller.motionTotals().moves - moves_before, 8);
  const auto lines = applyLines(dir.path + "/" + id + "/apply.jsonl");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0]["step"], "transmission_check");
  EXPECT_EQ(lines[0]["agree"], false);
  ASSERT_EQ(lines[0]["measurements"].size(), 4u);
  for (const auto& m : lines[0]["measurements"])
    EXPECT_EQ(m["agrees"].get<bool>(), m["joint"].get<int>() != 3) << m.dump();
  EXPECT_FALSE(apply::applyInterrupted(apply::ApplyJournal(dir.path + "/" + id + "/apply.jsonl")));
  std::ifstream in(dir.path + "/" + id + "/summary.txt");
  const std::string summary((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(summary.find("REFUSED"), std::string::npos) << summary;
  EXPECT_NE(summary.find("Transmissions measured"), std::string::npos) << summary;
  EXPECT_NE(summary.find("(DISAGREES)"), std::string::npos) << summary;
}

// A controller that does not serve while `reachable` is false: one still booting after a power
// cut (an IRC5 cold boot can outlast controller.irc5.restart_timeout_ms).
class GatedBackend final : public CellBackend {
 public:
  explicit GatedBackend(sim::SimulatedCellOptions options) : inner_(std::move(options)) {}
  const char* name() const override { return inner_.name(); }
  CellKnowledge knowledge() const override { return inner_.knowledge(); }
  std::unique_ptr<ConnectedCell> connect() override {
    if (!reachable) throw LinkError(LinkError::Kind::kTransient, "connection refused (booting)");
    return inner_.connect();
  }
  SimController& controller() { return inner_.cell().controller(); }
  RobotInfo identity() { return inner_.connect()->robot().robotInfo(); }
  std::atomic<bool> reachable{true};

 private:
  sim::SimBackend inner_;
};

ManagerSettings recoverySettingsIn(const std::string& dir) {
  ManagerSettings s = applySettingsIn(dir);
  s.controller_restart_timeout = std::chrono::milliseconds(300);
  s.recovery_retry = std::chrono::milliseconds(50);
  return s;
}

// The journal of an apply of `session` killed right after its backup (a power cut): the
// controller's values then, and joint 3's new value it was about to write.
std::array<double, 6> journalBegunApply(const std::string& dir, const std::string& session,
                                        const std::array<double, 6>& before,
                                        const RobotInfo& controller) {
  std::array<double, 6> written = before;
  written[2] = before[2] + 0.01;
  apply::ApplyJournal(dir + "/" + session + "/apply.jsonl")
      .append({{"step", "begin"},
               {"controller",
                {{"robot_type", controller.robot_type},
                 {"serial", controller.serial},
                 {"software_version", controller.software_version}}},
               {"before_rad", before},
               {"new_rad", written},
               {"changes", nlohmann::json::array()}});
  return written;
}

// A session calibrated to done by a daemon that then stops; its id, empty when it did not end done.
std::string calibrated(CellBackend& backend, const ManagerSettings& settings) {
  SessionManager manager(backend, settings);
  const std::string id = manager.start(manager.defaultRequest());
  return manager.waitIdle().state == SessionState::kDone ? id : "";
}

// Polls the status until `done` says so (at most 20 s).
SessionStatus until(SessionManager& manager,
                    const std::function<bool(const SessionStatus&)>& done) {
  SessionStatus s = manager.status();
  for (int i = 0; i < 2000 && !done(s); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    s = manager.status();
  }
  return s;
}

// Killed inside an apply, restarted while the controller still boots: the recovery cannot run.
// The daemon refuses every session, apply and verification meanwhile, tries again by itself once
// the controller serves, finds that nothing was written and closes the apply without a write or
// a restart. A later apply, verified, then survives the next restart of the daemon untouched.
TEST(SessionManagerRecovery, AnApplyInterruptedWhileTheControllerBootsNeverUndoesALaterOne) {
  const TempDir dir;
  GatedBackend backend(cellFor(6));
  const ManagerSettings settings = recoverySettingsIn(dir.path);
  const std::string first = calibrated(backend, settings);
  ASSERT_FALSE(first.empty());
  const std::array<double, 6> before = backend.controller().calOffsets();
  journalBegunApply(dir.path, first, before, backend.identity());
  const long restarts = backend.controller().restartCount();

  backend.reachable = false;
  SessionManager manager(backend, settings);
  EXPECT_EQ(manager.recoverInterruptedApplies(), 1);
  SessionStatus s = until(
      manager, [](const SessionStatus& st) { return st.state == SessionState::kUnrecovered; });
  ASSERT_EQ(s.state, SessionState::kUnrecovered) << s.message;
  // What to check on the FlexPendant: the apply's backup.
  char backup[32];
  std::snprintf(backup, sizeof backup, "rob1_3 %.6f", before[2]);
  EXPECT_NE(s.message.find(backup), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("acknowledge"), std::string::npos) << s.message;
  EXPECT_EQ(refusalOf([&] { manager.start(manager.defaultRequest()); }), "unrecovered");
  EXPECT_EQ(refusalOf([&] { manager.apply({first, true}); }), "unrecovered");
  EXPECT_EQ(refusalOf([&] { manager.verify({first}); }), "unrecovered");
  EXPECT_EQ(refusalOf([&] { manager.resume({}); }), "unrecovered");
  EXPECT_TRUE(
      apply::applyInterrupted(apply::ApplyJournal(dir.path + "/" + first + "/apply.jsonl")));

  backend.reachable = true;  // booted: the recovery is tried again without a command
  s = until(manager, [](const SessionStatus& st) {
    return st.state != SessionState::kUnrecovered && !isActive(st.state);
  });
  EXPECT_EQ(s.state, SessionState::kDone) << s.message;
  const auto lines = applyLines(dir.path + "/" + first + "/apply.jsonl");
  EXPECT_EQ(lines.back()["outcome"], "not_written");
  EXPECT_EQ(backend.controller().calOffsets(), before);
  EXPECT_EQ(backend.controller().restartCount(), restarts);  // nothing to take: no restart

  const std::string second = manager.start(manager.defaultRequest());
  ASSERT_EQ(manager.waitIdle().state, SessionState::kDone);
  manager.apply({second, true});
  const SessionStatus applied = manager.waitIdle();
  ASSERT_EQ(applied.state, SessionState::kDone) << applied.message;
  ASSERT_NE(applied.apply.find("verified"), std::string::npos) << applied.apply;
  const std::array<double, 6> verified = backend.controller().calOffsets();
  EXPECT_NE(verified, before);

  SessionManager restarted(backend, settings);
  EXPECT_EQ(restarted.recoverInterruptedApplies(), 0);
  EXPECT_EQ(restarted.waitIdle().state, SessionState::kIdle);
  EXPECT_EQ(backend.controller().calOffsets(), verified);
}

// The controller holds values an interrupted apply neither backed up nor wrote (joint 4 was
// calibrated since), and a session folder copied from another cell holds that cell's
// interrupted apply: nothing is written over either, the daemon refuses sessions and says which
// values to check, and the technician, having checked them, acknowledges; then sessions run.
TEST(SessionManagerRecovery, ValuesNeitherBackedUpNorWrittenAreKeptUntilAcknowledged) {
  const TempDir dir;
  GatedBackend backend(cellFor(6));
  const ManagerSettings settings = recoverySettingsIn(dir.path);
  const std::string first = calibrated(backend, settings);
  ASSERT_FALSE(first.empty());
  const std::array<double, 6> before = backend.controller().calOffsets();
  journalBegunApply(dir.path, first, before, backend.identity());
  const double joint4 = before[3] + 0.02;
  backend.controller().writeCalOffset(4, joint4);
  // A session folder from another cell, its apply interrupted there.
  const std::string copied = "20200101T000000Z";
  std::filesystem::create_directory(dir.path + "/" + copied);
  std::filesystem::copy_file(dir.path + "/" + first + "/session.json",
                             dir.path + "/" + copied + "/session.json");
  RobotInfo other = backend.identity();
  other.serial = "6400-500123";
  journalBegunApply(dir.path, copied, before, other);

  SessionManager manager(backend, settings);
  EventLog log;
  manager.setEventSink(log.sink());
  EXPECT_EQ(manager.recoverInterruptedApplies(), 2);
  manager.waitIdle();
  SessionStatus s = manager.status();
  ASSERT_EQ(s.state, SessionState::kUnrecovered) << s.message;
  EXPECT_NE(s.message.find("6400-500123"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("neither this apply's backup nor its written value"), std::string::npos)
      << s.message;
  EXPECT_NEAR(backend.controller().calOffsets()[3], joint4, 1e-6);
  EXPECT_EQ(backend.controller().calOffsets()[2], before[2]);
  const auto events = log.of<ApplyEvent>();
  ASSERT_EQ(events.size(), 2u);
  for (const ApplyEvent& e : events) EXPECT_EQ(e.outcome, ApplyOutcome::kUnrecovered);
  // Tried again and again by the idle worker, it journals each finding once.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(applyLines(dir.path + "/" + first + "/apply.jsonl").size(), 2u);
  EXPECT_EQ(refusalOf([&] { manager.start(manager.defaultRequest()); }), "unrecovered");

  EXPECT_EQ(refusalOf([&] { manager.acknowledge({"", false}); }), "not_confirmed");
  EXPECT_EQ(refusalOf([&] { manager.acknowledge({"20990101T000000Z", true}); }), "not_found");
  EXPECT_EQ(manager.acknowledge({copied, true}), copied);
  EXPECT_EQ(manager.waitIdle().state, SessionState::kUnrecovered);  // the other one is still open
  EXPECT_EQ(manager.acknowledge({"", true}), first);
  EXPECT_EQ(manager.waitIdle().state, SessionState::kDone);
  for (const std::string& id : {first, copied}) {
    const auto lines = applyLines(dir.path + "/" + id + "/apply.jsonl");
    EXPECT_EQ(lines.back()["outcome"], "acknowledged") << id;
    EXPECT_EQ(lines[lines.size() - 2]["step"], "acknowledged") << id;
  }
  EXPECT_NEAR(backend.controller().calOffsets()[3], joint4, 1e-6);
  const std::string next = manager.start(manager.defaultRequest());
  EXPECT_FALSE(next.empty());
  manager.abort();
  manager.waitIdle();
}

// A verification session the daemon was killed in, mid-apply, is never resumed as a
// calibration (nor picked by a resume without an id), and is closed when its apply is recovered.
TEST(SessionManagerRecovery, AVerificationKilledMidApplyIsNeverResumedAndClosedOnRecovery) {
  const TempDir dir;
  GatedBackend backend(cellFor(6));
  const ManagerSettings settings = recoverySettingsIn(dir.path);
  const std::string first = calibrated(backend, settings);
  ASSERT_FALSE(first.empty());
  // The apply had written, restarted and begun its verification: two poses on disk.
  const std::array<double, 6> before = backend.controller().calOffsets();
  const std::array<double, 6> written =
      journalBegunApply(dir.path, first, before, backend.identity());
  backend.controller().writeCalOffset(3, written[2]);
  apply::ApplyJournal journal(dir.path + "/" + first + "/apply.jsonl");
  for (const char* step : {"written", "restarting", "restarted"}) journal.append({{"step", step}});
  SessionStore store(dir.path);
  SessionFile verification = store.readSession(first);
  verification.kind = SessionKind::kVerification;
  verification.verifies = first;
  const std::string vid = store.create(verification).id;
  {
    std::ifstream in(store.journalPath(first));
    std::ofstream out(store.journalPath(vid));
    std::string line;
    for (int i = 0; i < 2 && std::getline(in, line); ++i) out << line << "\n";
  }

  SessionManager manager(backend, settings);
  EXPECT_EQ(manager.recoverInterruptedApplies(), 1);
  EXPECT_EQ(manager.waitIdle().state, SessionState::kDone);
  for (int i = 0; i < 6; ++i)  // the backup restored
    EXPECT_NEAR(backend.controller().calOffsets()[i], before[i], 1e-6) << i;
  EXPECT_EQ(refusalOf([&] { manager.resume({}); }), "not_found");
  EXPECT_EQ(refusalOf([&] { manager.resume({vid}); }), "verification");
  bool listed = false;
  for (const SessionInfo& info : manager.sessions())
    if (info.id == vid) {
      listed = true;
      EXPECT_EQ(info.kind, SessionKind::kVerification);
      EXPECT_EQ(info.verifies, first);
      EXPECT_NE(info.closed.find("recovered"), std::string::npos) << info.closed;
    }
  EXPECT_TRUE(listed);
}

}  // namespace
}  // namespace zerocal::service
