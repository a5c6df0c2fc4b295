#!/usr/bin/env python3
"""The web terminal in a real browser: Debian's headless Chromium driven by Selenium
(python3-selenium, chromium-driver) against `zerocald --sim`.

zerocald runs with a temporary data folder and token file, on ports 0; the web terminal's port is
read from its log. The browser reaches it through a small TCP relay in this script, so that the
test can drop every connection at once (a network that fails) and see the page reconnect.

What it checks, in the order a technician works: a bad token is refused with the daemon's words;
the right one logs in and shows the cell; a session started from the start page (its plan shown
first) advances pose by pose; Abort (one touch) stops it and the state is `aborted`; a reference
runs to its verdict; a restore against it (joint 3's zero moved by 0.4 deg between the two, the
daemon restarted) runs to its verdict; apply is refused until confirmed,
then runs; after the daemon's restart (its logins gone) the page asks for the token again; a
dropped connection reconnects and shows the current state; an operator's login is offered a check
and not the other kinds nor the apply, and the engineer's again everything. At 1280x800 and 390 px
wide, nothing overflows the width and every button is at least 48 px high.

Fails (never skips) when chromium, chromedriver or selenium is missing: scripts/install-deps.sh
installs them.
"""
import argparse
import os
import re
import select
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time

try:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait
except ImportError as e:  # a failure, not a skip: install-deps installs it
    print(f"FAIL: python3-selenium is not installed ({e}); run scripts/install-deps.sh")
    sys.exit(1)


class Relay:
    """Forwards TCP connections from a local port to the daemon's web port; drop() cuts them."""

    def __init__(self, target_port):
        self.target_port = target_port
        self.listener = socket.socket()
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind(("127.0.0.1", 0))
        self.listener.listen(64)
        self.port = self.listener.getsockname()[1]
        self.lock = threading.Lock()
        self.open = []
        threading.Thread(target=self.accept, daemon=True).start()

    def accept(self):
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            try:
                upstream = socket.create_connection(("127.0.0.1", self.target_port))
            except OSError:
                client.close()
                continue
            with self.lock:
                self.open += [client, upstream]
            threading.Thread(target=self.pump, args=(client, upstream), daemon=True).start()

    def pump(self, a, b):
        try:
            while True:
                ready, _, _ = select.select([a, b], [], [], 1.0)
                for s in ready:
                    data = s.recv(65536)
                    if not data:
                        raise OSError("closed")
                    (b if s is a else a).sendall(data)
        except OSError:
            pass
        for s in (a, b):
            try:
                s.close()
            except OSError:
                pass

    def drop(self):
        with self.lock:
            sockets, self.open = self.open, []
        for s in sockets:
            try:
                s.shutdown(socket.SHUT_RDWR)
                s.close()
            except OSError:
                pass


class Failure(Exception):
    pass


def check(condition, what):
    if not condition:
        raise Failure(what)
    print(f"ok: {what}")


OPERATOR_TOKEN = "browser-test-operator-0123456789"


def start_daemon(zerocald, workdir, extra=()):
    token = os.path.join(workdir, "token")
    with open(token, "w") as f:
        f.write("browser-test-token-0123456789\n")
    os.chmod(token, 0o600)
    operator_token = os.path.join(workdir, "operator-token")
    with open(operator_token, "w") as f:
        f.write(OPERATOR_TOKEN + "\n")
    os.chmod(operator_token, 0o600)
    log_path = os.path.join(workdir, "zerocald.log")
    log = open(log_path, "a")
    start = log.tell()
    command = [zerocald, "--sim", "--seed", "1", "--config", "/dev/null",
               "--data-dir", os.path.join(workdir, "sessions"),
               "--set", f"control.token_file={token}", "--set", "control.port=0",
               "--set", f"control.operator_token_file={operator_token}",
               "--set", "web.port=0",
               # ten times faster than a real cell: a session one can watch, in seconds
               "--set", "backend.sim_pace=0.1", *extra]
    daemon = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
    deadline = time.time() + 30
    while time.time() < deadline:
        with open(log_path) as f:
            f.seek(start)
            match = re.search(r"web terminal listening on http://127\.0\.0\.1:(\d+)/", f.read())
        if match:
            return daemon, int(match.group(1)), "browser-test-token-0123456789", log_path
        if daemon.poll() is not None:
            break
        time.sleep(0.1)
    with open(log_path) as f:
        print(f.read())
    raise Failure("zerocald did not name its web terminal's port")


def stop_daemon(daemon):
    daemon.terminate()
    try:
        daemon.wait(timeout=20)
    except subprocess.TimeoutExpired:
        daemon.kill()
        daemon.wait()


def browser():
    chromium = shutil.which("chromium")
    driver = shutil.which("chromedriver") or "/usr/bin/chromedriver"
    if not chromium or not os.path.exists(driver):
        print("FAIL: chromium and chromium-driver are needed; run scripts/install-deps.sh")
        sys.exit(1)
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu",
                     "--disable-dev-shm-usage", "--window-size=1280,800"):
        options.add_argument(argument)
    return webdriver.Chrome(service=Service(executable_path=driver), options=options)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--zerocald", required=True)
    parser.add_argument("--screenshots", default=os.environ.get("ZEROCAL_SCREENSHOTS"),
                        help="save a PNG of each page here, at 1280x800 and 390x844"
                             " (or the environment's ZEROCAL_SCREENSHOTS)")
    args = parser.parse_args()
    driver = browser()  # before the daemon: a missing browser fails with nothing left running
    workdir = tempfile.mkdtemp(prefix="zerocal-browser-")
    daemons = []
    relay = None
    log_path = os.path.join(workdir, "zerocald.log")

    def restart(extra):
        """Stops the daemon and starts it again on the same data folder with `extra` settings."""
        stop_daemon(daemons[-1])
        new, new_port, _, _ = start_daemon(args.zerocald, workdir, extra)
        daemons.append(new)
        relay.target_port = new_port
        relay.drop()

    started = time.time()
    try:
        daemon, port, token, log_path = start_daemon(args.zerocald, workdir)
        daemons.append(daemon)
        relay = Relay(port)
        run(driver, f"http://127.0.0.1:{relay.port}/", token, relay, restart, args.screenshots)
        print(f"PASS in {time.time() - started:.1f} s")
        return 0
    except Exception as e:  # noqa: BLE001 -- any failure is the test's
        print(f"FAIL: {e}")
        try:
            print("page text:", driver.find_element(By.TAG_NAME, "body").text)
            for entry in driver.get_log("browser"):
                print("console:", entry)
        except Exception:  # noqa: BLE001
            pass
        if os.path.exists(log_path):
            with open(log_path) as f:
                print("--- zerocald's log ---")
                print(f.read()[-6000:])
        return 1
    finally:
        driver.quit()
        if daemons:
            stop_daemon(daemons[-1])
        if relay:
            relay.listener.close()
        shutil.rmtree(workdir, ignore_errors=True)


def run(driver, base, token, relay, restart, screenshots):
    wait = WebDriverWait(driver, 30, poll_frequency=0.1)

    def element(id_):
        return driver.find_element(By.ID, id_)

    def text(id_):
        return element(id_).text

    def visible_page():
        return driver.execute_script("return document.body.dataset.page")

    def until(condition, what, timeout=30):
        try:
            WebDriverWait(driver, timeout, poll_frequency=0.1).until(lambda d: condition())
        except Exception as e:
            raise Failure(f"{what}: not within {timeout} s ({type(e).__name__})")
        print(f"ok: {what}")

    def shot(name, ready=None):
        """The page as it is now, at the tablet's size and the phone's (docs/web/*.png); with
        `ready`, at each size once it holds (a live page changes while it is pictured)."""
        if not screenshots:
            return
        os.makedirs(screenshots, exist_ok=True)
        for size, (width, height) in (("tablet", (1280, 800)), ("phone", (390, 844))):
            # The viewport itself at that size (a window's size includes its frame).
            driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {
                "width": width, "height": height, "deviceScaleFactor": 1,
                "mobile": size == "phone"})
            time.sleep(0.2)  # the layout settles
            if ready:
                until(ready, f"the {name} page as it is to be pictured ({size})")
            driver.save_screenshot(os.path.join(screenshots, f"{name}-{size}.png"))
        driver.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})

    def layout_fits(size):
        overflow = driver.execute_script(
            "return document.documentElement.scrollWidth - window.innerWidth")
        check(overflow <= 0, f"{size}: nothing wider than the window (overflow {overflow} px)")
        small = driver.execute_script(
            "return [...document.querySelectorAll('button')].filter(b => b.offsetParent !== null"
            " && b.getBoundingClientRect().height < 48).map(b => b.id || b.textContent)")
        check(small == [], f"{size}: every visible button at least 48 px high {small}")

    # -- log in -------------------------------------------------------------------------------
    driver.get(base)
    until(lambda: visible_page() == "login", "the login page is shown first")
    # A measurement, not a requirement checked here (docs/web.md, "Load and latency"): from the
    # navigation's start to the login field shown and usable, the first load, nothing cached.
    usable_ms, interactive_ms = driver.execute_script(
        "return [performance.getEntriesByName('zerocal-usable')[0].startTime,"
        " performance.getEntriesByType('navigation')[0].domInteractive]")
    check(element("token").is_enabled() and usable_ms > 0, "the login field is usable")
    print(f"measured: first page usable {usable_ms:.0f} ms after the navigation started"
          f" (DOM interactive at {interactive_ms:.0f} ms)")
    layout_fits("1280x800 login")
    shot("login")
    element("token").send_keys("not-the-token")
    element("login").click()
    until(lambda: "wrong token" in text("login-error"), "a bad token is refused: 'wrong token'")
    check(visible_page() == "login", "still on the login page after a bad token")
    element("token").clear()
    element("token").send_keys(token)
    element("login").click()
    until(lambda: visible_page() == "cell" and text("cell-state") == "idle",
          "logged in: the cell page, state idle")
    until(lambda: text("link") == "connected", "the WebSocket is connected")
    check(driver.get_cookie("zerocal_login") is not None
          and driver.get_cookie("zerocal_login")["httpOnly"], "the login is an HttpOnly cookie")
    check(driver.execute_script("return document.cookie") == "",
          "the page's script cannot read the login cookie")
    check("reference" in text("cell-suggestion"), "the daemon's suggestion is shown")
    check(not element("abort").is_displayed(), "no Abort while nothing runs")
    layout_fits("1280x800 cell")
    shot("cell")

    # -- start, progress, abort -------------------------------------------------------------------
    element("to-start").click()
    until(lambda: visible_page() == "start", "the start page")
    check(element("kinds").find_element(By.CSS_SELECTOR, "input[value=reference]").is_selected(),
          "the suggested kind (reference) is chosen")
    until(lambda: "poses" in text("plan-poses") and element("start-confirm").is_enabled(),
          "the plan's prediction is shown before anything moves", timeout=60)
    check("deg" in text("plan-table"), "predicted sigmas in degrees")
    check("cell time not predicted" in text("plan-time"),
          "no cell time predicted before the daemon has finished a session")
    shot("start")
    element("start-confirm").click()
    until(lambda: visible_page() == "progress", "the progress page once started")
    until(lambda: element("abort").is_displayed(), "Abort is visible while the robot can move")

    def recorded():
        m = re.search(r"pose (\d+) of (\d+)", text("progress-pose"))
        return int(m.group(1)) if m else 0

    until(lambda: recorded() >= 1, "progress: pose 1")
    first = recorded()
    until(lambda: recorded() > first, "progress advances pose by pose", timeout=60)
    check(element("spot").get_attribute("visibility") in ("visible", "hidden"),
          "the detector is drawn")
    def spot_drawn():
        return (text("detector-caption").startswith("spot at")
                and element("spot").get_attribute("visibility") == "visible")

    until(spot_drawn, "the spot is drawn live on the detector while the robot measures",
          timeout=60)
    shot("progress", spot_drawn)
    element("abort").click()
    until(lambda: visible_page() == "cell" and text("cell-state") == "aborted",
          "after one touch on Abort the state is aborted")
    check(not element("abort").is_displayed(), "no Abort once the robot stopped")

    # -- a whole reference to its verdict -----------------------------------------------------
    element("to-start").click()
    until(lambda: element("start-confirm").is_enabled(), "the start page again", timeout=60)
    element("start-confirm").click()
    until(lambda: visible_page() == "result" and text("verdict") in ("USABLE", "NOT USABLE"),
          "a whole reference runs to its verdict", timeout=120)
    check(text("verdict") == "USABLE", "the reference is usable")
    reference_id = text("result-kind").split()[1].rstrip(":")
    check(len(element("result-table").find_elements(By.CSS_SELECTOR, "tbody tr")) == 4,
          "its four offsets are listed")
    layout_fits("1280x800 result")
    shot("result-reference")

    element("result-back").click()
    until(lambda: "check" in text("cell-suggestion"), "the suggestion is a check against it now")

    # -- months later: joint 3's motor replaced, the daemon started again ---------------------------
    # Its logins are gone with it: the page finds the WebSocket refused and asks for the token.
    restart(["--set", "backend.sim_zero_change_joint=3", "--set", "backend.sim_zero_change_deg=0.4"])
    until(lambda: visible_page() == "login", "after the daemon's restart the page asks to log in",
          timeout=20)
    element("token").send_keys(token)
    element("login").click()
    until(lambda: visible_page() == "cell" and text("link") == "connected", "logged in again")

    # -- a restore against the reference, and its apply -------------------------------------------
    element("to-start").click()
    element("kinds").find_element(By.CSS_SELECTOR, "input[value=restore]").click()
    until(lambda: element("start-confirm").is_enabled(), "a restore's start", timeout=60)
    check(re.search(r"about \d+ s of cell time \([0-9.]+ s a pose in the daemon's latest 1 session\)",
                    text("plan-time")), "the restore's cell time, predicted from the reference's")
    element("start-confirm").click()
    until(lambda: visible_page() == "result" and text("verdict") in ("USABLE", "NOT USABLE")
          and "restore" in text("result-kind"), "the restore runs to its verdict", timeout=120)
    check(text("verdict") == "USABLE", "the restore is usable")
    restore_id = text("result-kind").split()[1].rstrip(":")
    element("to-apply").click()
    until(lambda: visible_page() == "apply", "the apply page")
    check(not element("apply-confirm-box").is_selected(), "the confirmation is not ticked")
    check(driver.switch_to.active_element.get_attribute("id") == "apply-cancel",
          "Cancel has the focus: Enter cancels")
    shot("apply")
    element("apply-go").click()
    until(lambda: "not_confirmed" in text("apply-error"), "apply is refused until confirmed")
    element("apply-confirm-box").click()
    element("apply-go").click()
    until(lambda: text("apply-outcome") != "", "once confirmed the apply runs to an outcome",
          timeout=150)
    print("apply outcome:", text("apply-outcome"))
    check(text("apply-outcome").startswith(("verified", "rolled_back")),
          "the outcome is the daemon's: verified, or rolled back")

    # -- a dropped connection -------------------------------------------------------------------
    until(lambda: text("link") == "connected", "connected before the drop")
    element("apply-cancel").click()
    until(lambda: visible_page() == "result", "Cancel leaves the apply page")
    element("result-back").click()
    until(lambda: visible_page() == "cell" and text("cell-state") != "", "the cell page")
    sessions_and_history(driver, element, text, visible_page, until, shot, layout_fits,
                         reference_id, restore_id)
    state = text("cell-state")
    relay.drop()
    until(lambda: text("link") != "connected", "the page shows the connection lost", timeout=10)
    until(lambda: text("link") == "connected", "and reconnects by itself", timeout=20)
    until(lambda: text("cell-state") == state and text("status-line") != "",
          f"showing the current state after the reconnect ({state})")

    # -- an operator: checks and abort, and nothing else offered ---------------------------------
    element("logout").click()
    until(lambda: visible_page() == "login", "logged out")
    element("token").send_keys(OPERATOR_TOKEN)
    element("login").click()
    until(lambda: text("link") == "connected (operator: checks and abort)",
          "the operator's login says whose it is")
    element("to-start").click()
    until(lambda: visible_page() == "start", "the operator's start page")
    kinds = element("kinds")
    for kind in ("reference", "restore", "calibration"):
        check(not kinds.find_element(By.CSS_SELECTOR, f"input[value={kind}]").is_displayed(),
              f"an operator is not offered a {kind}")
    check(kinds.find_element(By.CSS_SELECTOR, "input[value=check]").is_selected(),
          "an operator's start page chooses the check")
    until(lambda: element("start-confirm").is_enabled(), "the operator's check can start",
          timeout=60)
    element("start-cancel").click()
    element("to-result").click()
    until(lambda: visible_page() == "result" and text("verdict") != "–", "the operator's result")
    check(not element("to-apply").is_displayed(), "an operator is not offered the apply")
    element("result-back").click()
    element("logout").click()
    until(lambda: visible_page() == "login", "the operator logged out")
    element("token").send_keys(token)
    element("login").click()
    until(lambda: text("link") == "connected", "the engineer logged in again")
    element("to-start").click()
    until(lambda: visible_page() == "start", "the engineer's start page")
    check(element("kinds").find_element(By.CSS_SELECTOR, "input[value=restore]").is_displayed(),
          "the engineer is offered every kind again")
    element("start-cancel").click()

    # -- the phone's width ----------------------------------------------------------------------
    driver.set_window_size(390, 844)
    time.sleep(0.3)
    layout_fits("390 px cell")


def sessions_and_history(driver, element, text, visible_page, until, shot, layout_fits,
                         reference_id, restore_id):
    """The Sessions page with its reports, and the History page with its trend plots, after a
    reference, an aborted session, a restore and its apply."""
    def rows(table):
        return {r.get_attribute("data-session"): r
                for r in element(table).find_elements(By.CSS_SELECTOR, "tbody tr")}

    def fits_both(page):
        layout_fits(f"1280x800 {page}")
        driver.set_window_size(390, 844)
        time.sleep(0.2)
        layout_fits(f"390 px {page}")
        driver.set_window_size(1280, 800)

    def cell(row, cls):
        return row.find_element(By.CSS_SELECTOR, "td." + cls.replace(" ", ".")).text

    element("to-sessions").click()
    until(lambda: visible_page() == "sessions" and reference_id in rows("sessions-table")
          and restore_id in rows("sessions-table"), "the Sessions page lists the sessions")
    listed = rows("sessions-table")
    check(cell(listed[reference_id], "kind") == "reference"
          and cell(listed[reference_id], "verdict-cell") == "USABLE",
          "the reference is listed: kind reference, USABLE")
    check(cell(listed[restore_id], "kind") == "restore"
          and cell(listed[restore_id], "verdict-cell") == "USABLE",
          "the restore is listed: kind restore, USABLE")
    check(any(cell(r, "verdict-cell") == "not finished" for r in listed.values()),
          "the aborted session is listed as not finished")
    ids = list(listed)
    check(ids == sorted(ids, reverse=True), "newest first")
    check("of %d" % len(listed) in text("sessions-summary"), "the count of sessions is shown")
    link = listed[restore_id].find_element(By.LINK_TEXT, "report").get_attribute("href")
    check(link.endswith(f"/sessions/{restore_id}/report.html"), "a link to the session's report")
    # The report as the logged-in browser gets it (the login cookie goes with it).
    fetched = driver.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        "fetch(arguments[0], {credentials: 'same-origin'})"
        ".then(async r => done([r.status, await r.text()])).catch(e => done([0, String(e)]));", link)
    check(fetched[0] == 200 and restore_id in fetched[1] and "<html" in fetched[1].lower(),
          f"the report is served to the logged-in browser ({fetched[0]})")
    fits_both("sessions")
    shot("sessions")
    element("sessions-back").click()

    element("to-history").click()
    until(lambda: visible_page() == "history" and restore_id in rows("history-table"),
          "the History page shows the sessions recorded")
    recorded = rows("history-table")
    check(reference_id in recorded and cell(recorded[reference_id], "kind") == "reference",
          "the reference is in the robot's history")
    check(cell(recorded[restore_id], "kind") == "restore"
          and "±" in cell(recorded[restore_id], "offset"),
          "the restore is in it with its offsets and sigma")
    check(any(re.search(r"apply (verified|rolled_back)", cell(r, "events"))
              for r in recorded.values()), "the apply is among the controller events")
    # The plots show the changes since the reference the restore compared with: the restore's and
    # its verification's, not the reference's own offsets (another scale).
    check(f"change since reference {reference_id}" in text("history-trend"),
          "the trend plots say they show the changes since the reference")
    compared = {sid: r for sid, r in recorded.items()
                if cell(r, "kind") in ("check", "restore", "verification")}
    for k, name in enumerate(("delta2_deg", "delta3_deg", "delta4_deg", "delta5_deg")):
        svg = element("history-plots").find_element(By.CSS_SELECTOR, f"svg[data-offset={name}]")
        drawn = sorted(p.get_attribute("data-session")
                       for p in svg.find_elements(By.CSS_SELECTOR, "circle.point"))
        valued = sorted(sid for sid, r in compared.items()
                        if r.find_elements(By.CSS_SELECTOR, "td.offset")[k].text != "withheld")
        withheld = len(svg.find_elements(By.CSS_SELECTOR, "circle.withheld"))
        check(drawn == valued and len(drawn) >= 1 and withheld == len(compared) - len(valued)
              and reference_id not in drawn,
              f"the {name} plot has a point per session with a value ({len(drawn)}),"
              f" {withheld} withheld")
        bars = svg.find_elements(By.CSS_SELECTOR, "line.bar")
        check(len(bars) == len(drawn), f"each {name} point has its error bar")
    fits_both("history")
    shot("history")
    element("history-back").click()
    until(lambda: visible_page() == "cell", "back on the cell page")


if __name__ == "__main__":
    sys.exit(main())
