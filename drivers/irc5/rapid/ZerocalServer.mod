MODULE ZerocalServer
    !
    ! zerocal's socket server for an ABB IRC5 (RobotWare 5.x/6.x, option 616-1 PC Interface or
    ! 672-1 Socket Messaging). Written from the grammar in docs/irc5.md; wire compatible with the
    ! open_abb protocol (same codes, parameter counts, reply shapes, port 5000) so that open_abb
    ! clients work unchanged. Differences from upstream, each on purpose:
    !   - joints are replied with 5 decimals, XYZ with 3, quaternions with 6 (RAPID's num is a
    !     32-bit float: 5 decimals is its resolution near 100 deg);
    !   - every reply ends with LF and fits in 80 characters;
    !   - requests are framed by '#': bytes are collected until '#' arrives, so a request split
    !     across TCP segments or followed by a stray LF does not desynchronise the stream, and a
    !     request without '#' is answered with its own code and ok = 0, never with the previous one;
    !   - a move replies only when the robot has stopped at the target (WaitRob \InPos);
    !   - joint targets are checked against the MOC joint bounds before moving (ok = 0, no motion);
    !   - a client silent for kReceiveTimeout seconds is dropped, so a dead client cannot wedge the
    !     server (clients send 00 as a heartbeat);
    !   - the bind address is a constant to set per cell, not 127.0.0.1;
    !   - extensions only in codes 40..49; codes 30..36 (buffered and circular moves) reply ok = 0;
    !   - a spot search (47, 49): a spiral driven without stopping, the joints latched by an
    !     interrupt on a light signal from the PSD.
    !
    ! Request:  code SP *(param SP) "#"   e.g. "04 #", "02 +10.00000 -5.25000 ... #"
    ! Reply:    rcode SP ok SP [data] LF  e.g. "4 1 10.00000 -5.25000 0.00000 0.00000 90.00000 0.00000"

    ! ---- Configuration: edit for the cell --------------------------------------------------
    ! The controller's address on the network the PC uses (192.168.125.1 = service port).
    CONST string kBindAddress := "192.168.125.1";
    CONST num kPort := 5000;
    ! Seconds without a request before the client is considered dead.
    CONST num kReceiveTimeout := 60;
    ! Seconds a request may stay without its '#' before it is answered as a bad message.
    CONST num kFragmentTimeout := 1;

    ! The spot search (47, 49): the digital input that a comparator on the PSD amplifier's SUM
    ! output drives high while light is on the detector (docs/irc5.md, "The spot search").
    ! Define it in the I/O configuration under this name; without it 47 replies ok = 0.
    CONST string kSearchSignal := "diZerocalSpot";
    ! Zone of the search's waypoints (mm): small against their spacing (pitch / 2, ~4 mm).
    CONST num kSearchZone := 1;

    ! Decimals of joint angles in replies. 5 matches num's float32 resolution near 100 deg; if
    ! NumToStr refuses 5 on this RobotWare, set 4 (the client reads either).
    CONST num kJointDecimals := 5;

    ! ---- Protocol constants ----------------------------------------------------------------
    CONST num kMaxParams := 10;
    CONST string kLf := "\0A";

    ! ---- State -----------------------------------------------------------------------------
    VAR socketdev server_socket;
    VAR socketdev client_socket;
    VAR string client_ip;
    VAR bool client_connected := FALSE;

    ! Bytes received but not yet used: at most one request (80 characters) plus a fragment.
    VAR string pending := "";
    VAR string request := "";

    VAR num code := 0;
    VAR num params{kMaxParams};
    VAR num n_params := 0;
    VAR bool parsed_ok := FALSE;

    VAR num ok := 0;
    VAR string data := "";
    VAR bool close_after := FALSE;
    VAR bool restart_after := FALSE;

    ! Joint bounds from MOC.cfg ARM, converted to degrees at start-up.
    VAR num lower_deg{6};
    VAR num upper_deg{6};

    PERS tooldata zc_tool := [TRUE,[[0,0,0],[1,0,0,0]],[0.001,[0,0,0.001],[1,0,0,0],0,0,0]];
    PERS wobjdata zc_wobj := [FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    VAR speeddata zc_speed := [100,50,0,0];
    VAR zonedata zc_zone;

    ! The spot search: the signal and its interrupt, the spiral (47), the latched joints.
    VAR signaldi search_di;
    VAR intnum search_int;
    VAR num search_rows := 0;
    VAR num search_centre{6};
    VAR num search_per_u{6};
    VAR num search_per_v{6};
    VAR bool search_found := FALSE;
    VAR jointtarget search_hit;
    VAR speeddata search_speed;
    VAR zonedata search_zone;

    VAR jointtarget joint_target;
    VAR robtarget cart_target;
    VAR jointtarget joints_now;
    VAR robtarget pose_now;

    PROC main()
        ! As upstream: MoveL may change the arm configuration, and the wrist may pass near its
        ! singularity, rather than stop with a configuration error.
        ConfL \Off;
        SingArea \Wrist;
        zc_zone := fine;
        ReadJointBounds;
        WHILE TRUE DO
            Serve;
        ENDWHILE
    ENDPROC

    ! Listens and serves one client at a time until a socket error, then returns so that main
    ! starts over with fresh sockets.
    PROC Serve()
        ServerCreate;
        WHILE TRUE DO
            SocketAccept server_socket, client_socket \ClientAddress:=client_ip \Time:=WAIT_MAX;
            client_connected := TRUE;
            pending := "";
            TPWrite "ZerocalServer: client " + client_ip;
            WHILE client_connected DO
                IF ReceiveRequest() THEN
                    HandleRequest;
                    SendReply;
                    IF close_after client_connected := FALSE;
                    IF restart_after THEN
                        SocketClose client_socket;
                        SocketClose server_socket;
                        WarmStart;
                    ENDIF
                ENDIF
            ENDWHILE
            SocketClose client_socket;
            TPWrite "ZerocalServer: client gone, listening again";
        ENDWHILE
    ERROR
        TPWrite "ZerocalServer: socket error " + NumToStr(ERRNO, 0) + ", restarting";
        SocketClose client_socket;
        SocketClose server_socket;
        WaitTime 1;
        RETURN;
    ENDPROC

    PROC ServerCreate()
        SocketClose server_socket;
        SocketCreate server_socket;
        SocketBind server_socket, kBindAddress, kPort;
        SocketListen server_socket;
        TPWrite "ZerocalServer: listening on " + kBindAddress + ":" + NumToStr(kPort, 0);
    ENDPROC

    ! MOC ARM bounds are radians; the protocol speaks degrees.
    PROC ReadJointBounds()
        VAR num value;
        FOR i FROM 1 TO 6 DO
            ReadCfgData "/MOC/ARM/rob1_" + NumToStr(i, 0), "lower_joint_bound", value;
            lower_deg{i} := value * 180 / pi;
            ReadCfgData "/MOC/ARM/rob1_" + NumToStr(i, 0), "upper_joint_bound", value;
            upper_deg{i} := value * 180 / pi;
        ENDFOR
    ENDPROC

    ! Collects bytes until a '#' and leaves the request (up to and including '#') in `request`.
    ! Returns FALSE when the client is gone (closed, silent for kReceiveTimeout) and clears
    ! client_connected. A fragment without '#' that would exceed 80 characters, or that is not
    ! completed within kFragmentTimeout, is answered as a bad message with its own code.
    FUNC bool ReceiveRequest()
        VAR string chunk;
        VAR num hash;
        WHILE TRUE DO
            hash := StrFind(pending, 1, "#");
            IF hash <= StrLen(pending) THEN
                request := StrPart(pending, 1, hash);
                IF hash = StrLen(pending) THEN
                    pending := "";
                ELSE
                    pending := StrPart(pending, hash + 1, StrLen(pending) - hash);
                ENDIF
                RETURN TRUE;
            ENDIF
            IF StrLen(pending) = 0 THEN
                SocketReceive client_socket \Str:=chunk \Time:=kReceiveTimeout;
            ELSE
                SocketReceive client_socket \Str:=chunk \Time:=kFragmentTimeout;
            ENDIF
            IF StrLen(pending) + StrLen(chunk) > 80 THEN
                ! Not a request of ours: refuse it whole rather than guess where it ends.
                request := pending;
                pending := "";
                RETURN TRUE;
            ENDIF
            pending := pending + chunk;
        ENDWHILE
    ERROR
        IF ERRNO = ERR_SOCK_TIMEOUT AND StrLen(pending) > 0 THEN
            ! A request missing its '#': answer it (ok = 0) rather than merge it with the next.
            request := pending;
            pending := "";
            RETURN TRUE;
        ENDIF
        IF ERRNO = ERR_SOCK_TIMEOUT OR ERRNO = ERR_SOCK_CLOSED THEN
            client_connected := FALSE;
            RETURN FALSE;
        ENDIF
        RAISE;
    ENDFUNC

    ! Splits `request` into code and params with upstream's counting rule: a parameter counts
    ! only when a space follows it, so "02 1 2 3 4 5 6#" has five parameters and is refused.
    PROC ParseRequest()
        VAR num start;
        VAR num space;
        VAR num hash;
        VAR string body;
        n_params := 0;
        parsed_ok := FALSE;
        code := 0;
        hash := StrFind(request, 1, "#");
        body := StrPart(request, 1, hash - 1);
        space := StrFind(body, 1, " ");
        IF space > StrLen(body) OR space = 1 THEN
            RETURN;
        ENDIF
        IF NOT StrToVal(StrPart(body, 1, space - 1), code) THEN
            RETURN;
        ENDIF
        IF hash > StrLen(request) THEN
            ! No '#': answer with this request's code, ok = 0.
            RETURN;
        ENDIF
        start := space + 1;
        WHILE start <= StrLen(body) DO
            space := StrFind(body, start, " ");
            IF space > StrLen(body) THEN
                ! The last number touches '#': not counted (upstream's rule).
                start := StrLen(body) + 1;
            ELSEIF space = start THEN
                start := start + 1;
            ELSE
                IF n_params >= kMaxParams THEN
                    RETURN;
                ENDIF
                Incr n_params;
                IF NOT StrToVal(StrPart(body, start, space - start), params{n_params}) THEN
                    RETURN;
                ENDIF
                start := space + 1;
            ENDIF
        ENDWHILE
        parsed_ok := TRUE;
    ENDPROC

    ! TRUE when every joint of joint_target lies inside the MOC bounds.
    FUNC bool WithinBounds(jointtarget target)
        IF target.robax.rax_1 < lower_deg{1} OR target.robax.rax_1 > upper_deg{1} RETURN FALSE;
        IF target.robax.rax_2 < lower_deg{2} OR target.robax.rax_2 > upper_deg{2} RETURN FALSE;
        IF target.robax.rax_3 < lower_deg{3} OR target.robax.rax_3 > upper_deg{3} RETURN FALSE;
        IF target.robax.rax_4 < lower_deg{4} OR target.robax.rax_4 > upper_deg{4} RETURN FALSE;
        IF target.robax.rax_5 < lower_deg{5} OR target.robax.rax_5 > upper_deg{5} RETURN FALSE;
        IF target.robax.rax_6 < lower_deg{6} OR target.robax.rax_6 > upper_deg{6} RETURN FALSE;
        RETURN TRUE;
    ENDFUNC

    FUNC string JointsText(jointtarget j)
        RETURN NumToStr(j.robax.rax_1, kJointDecimals) + " " + NumToStr(j.robax.rax_2, kJointDecimals)
            + " " + NumToStr(j.robax.rax_3, kJointDecimals) + " " + NumToStr(j.robax.rax_4, kJointDecimals)
            + " " + NumToStr(j.robax.rax_5, kJointDecimals) + " " + NumToStr(j.robax.rax_6, kJointDecimals);
    ENDFUNC

    ! Sets ok, data and close_after for `request`.
    PROC HandleRequest()
        VAR num value;
        VAR num theta;
        VAR string which;
        ok := 0;
        data := "";
        close_after := FALSE;
        ParseRequest;
        IF NOT parsed_ok THEN
            IF StrFind(request, 1, "#") > StrLen(request) THEN
                data := "request without '#'";
            ENDIF
            RETURN;
        ENDIF

        TEST code
        CASE 0:
            ! Ping; also the client's heartbeat.
            IF n_params = 0 ok := 1;
        CASE 1:
            ! MoveL to x y z q1 q2 q3 q4 in the current tool and work object.
            IF n_params = 7 THEN
                cart_target := CRobT(\Tool:=zc_tool \WObj:=zc_wobj);
                cart_target.trans := [params{1}, params{2}, params{3}];
                cart_target.rot := NOrient([params{4}, params{5}, params{6}, params{7}]);
                ! Bounds before moving: the joints this pose needs, from the current configuration.
                joint_target := CalcJointT(cart_target, zc_tool \WObj:=zc_wobj);
                IF WithinBounds(joint_target) THEN
                    MoveL cart_target, zc_speed, zc_zone, zc_tool \WObj:=zc_wobj;
                    WaitRob \InPos;
                    ok := 1;
                ELSE
                    data := "out of bounds";
                ENDIF
            ENDIF
        CASE 2:
            ! MoveAbsJ to j1..j6 (deg).
            IF n_params = 6 THEN
                joint_target := CJointT();
                joint_target.robax := [params{1}, params{2}, params{3}, params{4}, params{5}, params{6}];
                IF WithinBounds(joint_target) THEN
                    MoveAbsJ joint_target, zc_speed, zc_zone, zc_tool \WObj:=zc_wobj;
                    WaitRob \InPos;
                    ok := 1;
                ELSE
                    data := "out of bounds";
                ENDIF
            ENDIF
        CASE 3:
            IF n_params = 0 THEN
                pose_now := CRobT(\Tool:=zc_tool \WObj:=zc_wobj);
                data := NumToStr(pose_now.trans.x, 3) + " " + NumToStr(pose_now.trans.y, 3) + " "
                    + NumToStr(pose_now.trans.z, 3) + " " + NumToStr(pose_now.rot.q1, 6) + " "
                    + NumToStr(pose_now.rot.q2, 6) + " " + NumToStr(pose_now.rot.q3, 6) + " "
                    + NumToStr(pose_now.rot.q4, 6);
                ok := 1;
            ENDIF
        CASE 4:
            IF n_params = 0 THEN
                joints_now := CJointT();
                data := JointsText(joints_now);
                ok := 1;
            ENDIF
        CASE 5:
            IF n_params = 0 THEN
                joints_now := CJointT();
                ! Unused external axes read 9E+09.
                data := NumToStr(joints_now.extax.eax_a, 2) + " " + NumToStr(joints_now.extax.eax_b, 2)
                    + " " + NumToStr(joints_now.extax.eax_c, 2) + " " + NumToStr(joints_now.extax.eax_d, 2)
                    + " " + NumToStr(joints_now.extax.eax_e, 2) + " " + NumToStr(joints_now.extax.eax_f, 2);
                ok := 1;
            ENDIF
        CASE 6:
            IF n_params = 7 THEN
                zc_tool.tframe.trans := [params{1}, params{2}, params{3}];
                zc_tool.tframe.rot := NOrient([params{4}, params{5}, params{6}, params{7}]);
                ok := 1;
            ENDIF
        CASE 7:
            IF n_params = 7 THEN
                zc_wobj.oframe.trans := [params{1}, params{2}, params{3}];
                zc_wobj.oframe.rot := NOrient([params{4}, params{5}, params{6}, params{7}]);
                ok := 1;
            ENDIF
        CASE 8:
            IF n_params = 4 THEN
                zc_speed := [params{1}, params{2}, params{3}, params{4}];
                ok := 1;
            ELSEIF n_params = 2 THEN
                zc_speed.v_tcp := params{1};
                zc_speed.v_ori := params{2};
                ok := 1;
            ENDIF
        CASE 9:
            ! fine-flag, zone_tcp (mm), zone_ori (mm), zone_ori (deg).
            IF n_params = 4 THEN
                IF params{1} = 1 THEN
                    zc_zone := fine;
                ELSE
                    zc_zone := [FALSE, params{2}, params{3}, params{3}, params{4}, params{3}, params{4}];
                ENDIF
                ok := 1;
            ENDIF
        CASE 30, 31, 32, 33, 34, 35, 36:
            data := "not supported";
        CASE 40:
            ! Stop. This server is single-task and blocks inside a move, so a stop takes effect
            ! between moves only; the emergency stop remains the safety function.
            IF n_params = 0 THEN
                StopMove;
                ClearPath;
                StartMove;
                ok := 1;
            ENDIF
        CASE 41:
            ! MOC MOTOR_CALIB cal_offset of motors 1..6 (radians, motor side), read only.
            IF n_params = 0 THEN
                FOR i FROM 1 TO 6 DO
                    ReadCfgData "/MOC/MOTOR_CALIB/rob1_" + NumToStr(i, 0), "cal_offset", value;
                    data := data + NumToStr(value, 6);
                    IF i < 6 data := data + " ";
                ENDFOR
                ok := 1;
            ENDIF
        CASE 42:
            ! Joint bounds (deg): parameter 0 = lower, 1 = upper.
            IF n_params = 1 AND (params{1} = 0 OR params{1} = 1) THEN
                FOR i FROM 1 TO 6 DO
                    IF params{1} = 0 THEN
                        data := data + NumToStr(lower_deg{i}, 3);
                    ELSE
                        data := data + NumToStr(upper_deg{i}, 3);
                    ENDIF
                    IF i < 6 data := data + " ";
                ENDFOR
                ok := 1;
            ENDIF
        CASE 45:
            ! Write MOC MOTOR_CALIB cal_offset (radians, motor side) of motor params{1}. The motion
            ! system takes it at the next restart (46). Values outside one motor turn are refused.
            IF n_params = 2 AND params{1} >= 1 AND params{1} <= 6 AND params{1} = Trunc(params{1})
                AND params{2} >= 0 AND params{2} < 2 * pi THEN
                WriteCfgData "/MOC/MOTOR_CALIB/rob1_" + NumToStr(params{1}, 0), "cal_offset",
                    params{2};
                ok := 1;
            ENDIF
        CASE 46:
            ! Restart so that written system parameters take effect: reply first, then warm start
            ! (the connection closes; the client reconnects when the server is back).
            IF n_params = 0 THEN
                ok := 1;
                restart_after := TRUE;
            ENDIF
        CASE 47:
            ! One row of the spot search's spiral: 0 = the centre's joints (deg), 1 and 2 = the
            ! joints per mm of spot along the PSD's u and v (deg/mm). Row 0 binds the signal.
            IF n_params = 7 AND (params{1} = 0 OR params{1} = 1 OR params{1} = 2) THEN
                IF params{1} = 0 THEN
                    search_rows := 0;
                    AliasIO kSearchSignal, search_di;
                ENDIF
                FOR i FROM 1 TO 6 DO
                    IF params{1} = 0 search_centre{i} := params{i + 1};
                    IF params{1} = 1 search_per_u{i} := params{i + 1};
                    IF params{1} = 2 search_per_v{i} := params{i + 1};
                ENDFOR
                search_rows := search_rows + 1;
                ok := 1;
            ENDIF
        CASE 48:
            ! Motor angles of motors 1..6 (radians, motor side), for measuring a transmission.
            IF n_params = 0 THEN
                FOR i FROM 1 TO 6 DO
                    data := data + NumToStr(ReadMotor(i), 6);
                    IF i < 6 data := data + " ";
                ENDFOR
                ok := 1;
            ENDIF
        CASE 49:
            ! One run of the spiral: pitch, from and to radius (mm), speed (mm/s). Every waypoint
            ! is checked first; then MoveAbsJ through them in small zones, without stopping,
            ! while an interrupt on the signal's rising edge latches the joints (SearchTrap) and
            ! the loop stops queueing waypoints. Replies "1" and the latched joints, or "0".
            IF n_params = 4 AND search_rows = 3 AND params{1} > 0 AND params{2} >= 0
                AND params{3} >= params{2} AND params{4} > 0 AND params{4} <= zc_speed.v_tcp THEN
                IF SearchRunWithinBounds() THEN
                    search_found := FALSE;
                    search_speed := [params{4}, zc_speed.v_ori, 0, 0];
                    search_zone := [FALSE, kSearchZone, kSearchZone, kSearchZone, 0.1,
                        kSearchZone, 0.1];
                    IDelete search_int;
                    CONNECT search_int WITH SearchTrap;
                    ISignalDI \Single, search_di, 1, search_int;
                    theta := 2 * pi * params{2} / params{1};
                    WHILE NOT search_found AND params{1} * theta / (2 * pi) <= params{3} + 0.000001 DO
                        SearchWaypoint theta;
                        MoveAbsJ joint_target, search_speed, search_zone, zc_tool \WObj:=zc_wobj;
                        theta := theta + (params{1} / 2)
                            / Larger(params{1} * theta / (2 * pi), params{1} / 2);
                    ENDWHILE
                    WaitRob \InPos;
                    IDelete search_int;
                    IF search_found THEN
                        data := "1 " + JointsText(search_hit);
                    ELSE
                        data := "0";
                    ENDIF
                    ok := 1;
                ELSE
                    data := "out of bounds";
                ENDIF
            ELSEIF search_rows <> 3 THEN
                data := "no search spiral";
            ENDIF
        CASE 98:
            IF n_params = 0 THEN
                data := GetSysInfo(\SerialNo) + "*" + GetSysInfo(\SWVersion) + "*"
                    + GetSysInfo(\RobotType);
                ok := 1;
            ENDIF
        CASE 99:
            close_after := TRUE;
        ENDTEST
    ERROR
        ! A pose the robot cannot reach (CalcJointT): refuse and return before any move.
        IF ERRNO = ERR_ROBLIMIT OR ERRNO = ERR_OUTSIDE_REACH THEN
            ok := 0;
            data := "unreachable";
            SkipWarn;
            RETURN;
        ENDIF
        ! 47 without the search signal defined in the I/O configuration.
        IF ERRNO = ERR_ALIASIO_DEF OR ERRNO = ERR_ALIASIO_TYPE THEN
            ok := 0;
            data := "no search signal " + kSearchSignal;
            search_rows := 0;
            SkipWarn;
            RETURN;
        ENDIF
        RAISE;
    ENDPROC

    ! The spiral's waypoint at angle theta (rad): centre + per_u x + per_v y, (x, y) = r (cos, sin),
    ! r = pitch theta / 2 pi; into joint_target. The same formula as the client's
    ! (forEachSearchWaypoint, include/zerocal/cell/search_move.h).
    PROC SearchWaypoint(num theta)
        VAR num r;
        VAR num x;
        VAR num y;
        r := params{1} * theta / (2 * pi);
        x := r * Cos(theta * 180 / pi);
        y := r * Sin(theta * 180 / pi);
        joint_target := CJointT();
        joint_target.robax.rax_1 := search_centre{1} + search_per_u{1} * x + search_per_v{1} * y;
        joint_target.robax.rax_2 := search_centre{2} + search_per_u{2} * x + search_per_v{2} * y;
        joint_target.robax.rax_3 := search_centre{3} + search_per_u{3} * x + search_per_v{3} * y;
        joint_target.robax.rax_4 := search_centre{4} + search_per_u{4} * x + search_per_v{4} * y;
        joint_target.robax.rax_5 := search_centre{5} + search_per_u{5} * x + search_per_v{5} * y;
        joint_target.robax.rax_6 := search_centre{6} + search_per_u{6} * x + search_per_v{6} * y;
    ENDPROC

    ! Every waypoint of the run in params{1..3} within the MOC bounds (checked before moving).
    FUNC bool SearchRunWithinBounds()
        VAR num theta;
        theta := 2 * pi * params{2} / params{1};
        WHILE params{1} * theta / (2 * pi) <= params{3} + 0.000001 DO
            SearchWaypoint theta;
            IF NOT WithinBounds(joint_target) RETURN FALSE;
            theta := theta + (params{1} / 2) / Larger(params{1} * theta / (2 * pi), params{1} / 2);
        ENDWHILE
        RETURN TRUE;
    ENDFUNC

    FUNC num Larger(num a, num b)
        IF a > b RETURN a;
        RETURN b;
    ENDFUNC

    ! The signal rose: latch where the arm is, and let the run's loop stop queueing waypoints.
    TRAP SearchTrap
        search_hit := CJointT();
        search_found := TRUE;
    ENDTRAP

    ! One write: "rcode ok data" + LF. Code 99 gets no reply (upstream's behaviour).
    PROC SendReply()
        VAR string reply;
        IF close_after RETURN;
        reply := NumToStr(code, 0) + " " + NumToStr(ok, 0) + " " + data;
        ! RAPID strings hold 80 characters; every reply above fits with its LF (longest: pose, 75).
        SocketSend client_socket \Str:=reply + kLf;
    ERROR
        IF ERRNO = ERR_SOCK_CLOSED THEN
            client_connected := FALSE;
            RETURN;
        ENDIF
        RAISE;
    ENDPROC

ENDMODULE
