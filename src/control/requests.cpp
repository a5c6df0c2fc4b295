// The control port's requests in the service's terms (protocol.h): apart from the server and
// the engine, so that what parses a request line is small enough to fuzz on its own.
#include <cmath>
#include <set>

#include "zerocal/control/protocol.h"

namespace zerocal::control {

using nlohmann::json;

namespace {

const std::set<std::string> kStartMembers{
    "id",        "cmd",       "token",    "plan",       "poses",
    "plan_file", "target_mm", "noise_mm", "placements", "even_if_not_usable",
    "kind",      "reference"};
const std::set<std::string> kContinueMembers{"id", "cmd", "token", "centre_mm"};

// [x, y, z] in mm, finite. Throws BadRequest naming `member`.
Eigen::Vector3d pointMember(const json& value, const std::string& member) {
  if (!value.is_array() || value.size() != 3 || !value[0].is_number() || !value[1].is_number() ||
      !value[2].is_number())
    throw BadRequest(member + ": expected [x, y, z] in mm");
  const Eigen::Vector3d p(value[0].get<double>(), value[1].get<double>(), value[2].get<double>());
  if (!p.allFinite()) throw BadRequest(member + ": not finite");
  return p;
}

const std::set<std::string> kResumeMembers{"id", "cmd", "token", "session", "skip_pose"};

const std::set<std::string> kApplyMembers{"id", "cmd", "token", "session", "confirm"};
const std::set<std::string> kVerifyMembers{"id", "cmd", "token", "session"};

}  // namespace

const char* planKindName(PlanKind kind) {
  switch (kind) {
    case PlanKind::kOptimal:
      return "optimal";
    case PlanKind::kI:
      return "I";
    case PlanKind::kII:
      return "II";
    case PlanKind::kMixed:
      return "mixed";
    case PlanKind::kFile:
      return "file";
  }
  return "?";
}

PlanKind parsePlanKind(const std::string& name) {
  for (auto kind :
       {PlanKind::kOptimal, PlanKind::kI, PlanKind::kII, PlanKind::kMixed, PlanKind::kFile})
    if (name == planKindName(kind)) return kind;
  throw BadRequest("plan: '" + name + "' is not one of optimal, I, II, mixed, file");
}

service::StartRequest parseStartRequest(const json& request,
                                        const service::StartRequest& defaults) {
  for (const auto& item : request.items())
    if (!kStartMembers.count(item.key())) throw BadRequest("unknown member '" + item.key() + "'");
  service::StartRequest r = defaults;
  if (request.contains("plan")) r.plan = parsePlanKind(optionalString(request, "plan"));
  if (request.contains("poses")) {
    const auto& p = request["poses"];
    if (!p.is_number_integer()) throw BadRequest("poses: expected an integer");
    if (p.get<long long>() < kMinimumPoses || p.get<long long>() > kMaxPlanPoses)
      throw BadRequest("poses: " + p.dump() + " is outside " + std::to_string(kMinimumPoses) +
                       ".." + std::to_string(kMaxPlanPoses));
    r.poses = p.get<int>();
  }
  r.plan_file = optionalString(request, "plan_file", r.plan_file);
  if (request.contains("target_mm") && !request["target_mm"].is_null())
    r.target_mm = pointMember(request["target_mm"], "target_mm");
  if (request.contains("noise_mm") && !request["noise_mm"].is_null()) {
    const auto& n = request["noise_mm"];
    if (!n.is_number()) throw BadRequest("noise_mm: expected a number");
    const double v = n.get<double>();
    if (!(v > 0 && v <= 10)) throw BadRequest("noise_mm: " + n.dump() + " is outside (0, 10]");
    r.noise_mm = v;
  }
  if (request.contains("placements")) {
    const auto& p = request["placements"];
    if (!p.is_number_integer() || p.get<long long>() < 1 ||
        p.get<long long>() > kMaxDefaultPlacements)
      throw BadRequest("placements: expected an integer 1.." +
                       std::to_string(kMaxDefaultPlacements));
    r.placements = p.get<int>();
  }
  if (request.contains("even_if_not_usable")) {
    if (!request["even_if_not_usable"].is_boolean())
      throw BadRequest("even_if_not_usable: expected true or false");
    r.even_if_not_usable = request["even_if_not_usable"].get<bool>();
  }
  if (request.contains("kind")) {
    const std::string kind = optionalString(request, "kind");
    // A verification is the daemon's own, after an apply (the `verify` request asks for one).
    if (kind == "calibration" || kind == "calibrate")
      r.kind = SessionKind::kCalibration;
    else if (kind == "reference")
      r.kind = SessionKind::kReference;
    else if (kind == "check")
      r.kind = SessionKind::kCheck;
    else if (kind == "restore")
      r.kind = SessionKind::kRestore;
    else
      throw BadRequest("kind: '" + kind + "' is not one of calibration, reference, check, restore");
  }
  r.reference = optionalString(request, "reference", r.reference);
  if (!r.reference.empty() && r.kind != SessionKind::kCheck && r.kind != SessionKind::kRestore)
    throw BadRequest("reference: only a check or a restore is measured against a reference");
  return r;
}

service::ContinueRequest parseContinueRequest(const json& request) {
  for (const auto& item : request.items())
    if (!kContinueMembers.count(item.key()))
      throw BadRequest("unknown member '" + item.key() + "'");
  service::ContinueRequest r;
  if (request.contains("centre_mm") && !request["centre_mm"].is_null())
    r.centre_mm = pointMember(request["centre_mm"], "centre_mm");
  return r;
}

service::ResumeRequest parseResumeRequest(const json& request) {
  for (const auto& item : request.items())
    if (!kResumeMembers.count(item.key())) throw BadRequest("unknown member '" + item.key() + "'");
  service::ResumeRequest r;
  r.session = optionalString(request, "session");
  if (request.contains("skip_pose")) {
    const auto& p = request["skip_pose"];
    if (!p.is_number_integer() || p.get<long long>() < 1 || p.get<long long>() > kMaxPlanPoses)
      throw BadRequest("skip_pose: expected a pose number 1.." + std::to_string(kMaxPlanPoses));
    r.skip_pose = p.get<int>();
  }
  return r;
}

service::ApplyRequest parseApplyRequest(const json& request) {
  for (const auto& item : request.items())
    if (!kApplyMembers.count(item.key())) throw BadRequest("unknown member '" + item.key() + "'");
  service::ApplyRequest r;
  r.session = optionalString(request, "session");
  if (request.contains("confirm")) {
    if (!request["confirm"].is_boolean()) throw BadRequest("confirm: expected true or false");
    r.confirm = request["confirm"].get<bool>();
  }
  return r;
}

service::AcknowledgeRequest parseAcknowledgeRequest(const json& request) {
  // The same members as an apply: the session and the technician's confirmation.
  const service::ApplyRequest a = parseApplyRequest(request);
  return {a.session, a.confirm};
}

service::VerifyRequest parseVerifyRequest(const json& request) {
  for (const auto& item : request.items())
    if (!kVerifyMembers.count(item.key())) throw BadRequest("unknown member '" + item.key() + "'");
  return {optionalString(request, "session")};
}

SessionsPage parseSessionsRequest(const json& request) {
  SessionsPage page;
  if (request.contains("limit") && !request["limit"].is_null()) {
    const auto& l = request["limit"];
    if (!l.is_number_integer()) throw BadRequest("limit: expected an integer");
    if (l.get<long long>() < 1 || l.get<long long>() > SessionsPage::kMaxLimit)
      throw BadRequest("limit: " + l.dump() + " is outside 1.." +
                       std::to_string(SessionsPage::kMaxLimit));
    page.limit = l.get<int>();
  }
  page.cursor = optionalString(request, "cursor");
  return page;
}

}  // namespace zerocal::control
