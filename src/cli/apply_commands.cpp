#include "apply_commands.h"

#include "moved_commands.h"

namespace zerocal::cli {

void addApplyCommands(CLI::App& app, ApplyCommands& commands) {
  ApplyArgs& a = commands.args;
  commands.apply = app.add_subcommand(
      "apply",
      "apply a session's offsets online through zerocald: back up the controller's MOC "
      "MOTOR_CALIB cal_offset values, write the new ones, restart, verify by measurement, roll "
      "back when wrong (the MOC.cfg file apply is zerocal-lab apply)");
  auto* c = commands.apply;
  c->add_option("session", a.session, "the session id")->required();
  c->add_flag("--confirm", a.confirm,
              "write the new values into the controller and restart it (backed up, verified by "
              "measurement, rolled back when wrong)");
  addConnectionOptions(c, a.client);
  c->add_flag("--json", a.client.json, "the daemon's events, one per line");
  // The file apply's options, so that its command line reaches the message naming zerocal-lab.
  const char* moved = "Moved to zerocal-lab (the MOC.cfg file apply)";
  c->add_option("--moc", a.moc_file, "zerocal-lab apply DIR --moc MOC.cfg --out NEW.cfg")
      ->group(moved);
  c->add_option("--out", a.out_file)->group(moved);
  c->add_option("--robot", a.robot)->group(moved);
  c->add_flag("--unconfirmed-transmission", a.unconfirmed_transmission)->group(moved);
}

int runApplyCommands(const ApplyCommands& commands, const std::vector<std::string>& words,
                     std::ostream& out, std::ostream& err) {
  const ApplyArgs& a = commands.args;
  if (!a.moc_file.empty() || !a.out_file.empty() || !a.robot.empty() || a.unconfirmed_transmission)
    return refuseMovedCommand("apply --moc", commandLine(words), err);
  if (!a.confirm) {
    err << "zerocal apply: applying online writes the robot's calibration and restarts the "
           "controller; give --confirm to do it (the MOC.cfg file apply is zerocal-lab apply "
           "DIR --moc MOC.cfg --out NEW.cfg)\n";
    return kClientBadRequest;
  }
  ClientArgs client = a.client;
  client.command = "apply";
  client.session = a.session;
  client.confirm = true;
  // Never the one-line redraw: every step of an apply is worth keeping on the screen.
  return runClient(client, out, err, false);
}

}  // namespace zerocal::cli
