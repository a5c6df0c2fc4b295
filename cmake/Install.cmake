# What `cmake --install` installs, at paths that follow the prefix so that they cannot disagree:
# the unit runs the zerocald that was installed, with the configuration that was installed
# (ZEROCAL_CONFDIR, also the programs' compiled-in default). The unit, the udev rule and the
# sysusers.d file go where systemd and udev read them: the vendor folders under /usr for the prefix
# /usr (the package), the administrator's folders in /etc for any other prefix (udev reads no
# rules under /usr/local or /opt). Each folder can be set with -D.
if(CMAKE_INSTALL_PREFIX STREQUAL "/usr")
  set(_zerocal_system_dir /usr/lib)
else()
  set(_zerocal_system_dir /etc)
endif()
if(NOT DEFINED ZEROCAL_SYSTEMD_UNITDIR)
  set(ZEROCAL_SYSTEMD_UNITDIR ${_zerocal_system_dir}/systemd/system)
endif()
if(NOT DEFINED ZEROCAL_UDEV_RULESDIR)
  set(ZEROCAL_UDEV_RULESDIR ${_zerocal_system_dir}/udev/rules.d)
endif()
if(NOT DEFINED ZEROCAL_SYSUSERSDIR)
  set(ZEROCAL_SYSUSERSDIR ${_zerocal_system_dir}/sysusers.d)
endif()
set(ZEROCAL_BINDIR ${CMAKE_INSTALL_FULL_BINDIR})

install(TARGETS zerocal zerocal-lab zerocald zerocal-sim RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

# Configuration: every key at its default, the drop-in folder, the shipped robots, worlds and PSD
# files. The token is not installed: the package's postinst makes one (docs/daemon.md).
install(FILES config/zerocald.yaml config/psd.yaml config/psd-map.yaml
        DESTINATION ${ZEROCAL_CONFDIR})
install(DIRECTORY config/robots config/worlds DESTINATION ${ZEROCAL_CONFDIR})
install(DIRECTORY DESTINATION ${ZEROCAL_CONFDIR}/zerocald.d)

# The service: unit, user and group, the board's udev rule.
configure_file(config/zerocald.service.in ${PROJECT_BINARY_DIR}/config/zerocald.service @ONLY)
configure_file(config/sysusers/zerocal.conf ${PROJECT_BINARY_DIR}/config/sysusers/zerocal.conf
               @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/config/zerocald.service DESTINATION ${ZEROCAL_SYSTEMD_UNITDIR})
install(FILES ${PROJECT_BINARY_DIR}/config/sysusers/zerocal.conf
        DESTINATION ${ZEROCAL_SYSUSERSDIR})

# The udev rule, the man pages and the shell completions: the Debian package installs these with
# debhelper's tools (dh_installudev, dh_installman, dh_bash-completion; debian/), and turns this off.
option(ZEROCAL_INSTALL_EXTRAS "Install the udev rule, the man pages and the shell completions" ON)
if(ZEROCAL_INSTALL_EXTRAS)
  install(FILES config/udev/60-zerocal-usb1408fs.rules DESTINATION ${ZEROCAL_UDEV_RULESDIR})
endif()

# The web terminal's page files (docs/web.md), where web.root's default finds them.
install(DIRECTORY web/ DESTINATION ${CMAKE_INSTALL_DATADIR}/zerocal/web)

# The RAPID server module, for the controller (docs/irc5.md loads it from here).
install(FILES drivers/irc5/rapid/ZerocalServer.mod DESTINATION ${CMAKE_INSTALL_DATADIR}/zerocal/rapid)

# Bash completion of the commands and options (asked of the program's --help as one types); one
# file per program, since bash-completion loads a completion by the name of the command.
if(ZEROCAL_INSTALL_EXTRAS)
  foreach(program zerocal zerocal-lab zerocald zerocal-sim)
    install(FILES config/bash-completion/zerocal
            DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions RENAME ${program})
  endforeach()
endif()

# Man pages from each program's --help (help2man, scripts/install-deps.sh).
option(ZEROCAL_MAN_PAGES "Make and install man pages with help2man" ON)
if(ZEROCAL_MAN_PAGES)
  find_program(ZEROCAL_HELP2MAN help2man REQUIRED)
  set(_zerocal_man_pages "")
  function(zerocal_man_page program section name)
    set(out ${PROJECT_BINARY_DIR}/man/${program}.${section})
    add_custom_command(
      OUTPUT ${out}
      COMMAND ${CMAKE_COMMAND} -E make_directory ${PROJECT_BINARY_DIR}/man
      COMMAND ${ZEROCAL_HELP2MAN} --no-info --no-discard-stderr --section ${section} --name ${name}
              --output ${out} $<TARGET_FILE:${program}>
      DEPENDS ${program}
      COMMENT "man page ${program}(${section})"
      VERBATIM)
    if(ZEROCAL_INSTALL_EXTRAS)
      install(FILES ${out} DESTINATION ${CMAKE_INSTALL_MANDIR}/man${section})
    endif()
    set(_zerocal_man_pages ${_zerocal_man_pages} ${out} PARENT_SCOPE)
  endfunction()
  zerocal_man_page(zerocal 1 "the technician's client of zerocald, the calibration daemon")
  zerocal_man_page(zerocal-lab 1 "calibrate robot joint offsets offline: engine, PSD, report, experiments")
  zerocal_man_page(zerocald 8 "the zerocal cell daemon")
  zerocal_man_page(zerocal-sim 1 "simulated ABB IRC5 controller for zerocal")
  add_custom_target(man ALL DEPENDS ${_zerocal_man_pages})
endif()
