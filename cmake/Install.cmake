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

# Completion of the commands, options and session ids for bash, zsh and fish (asked of the
# program's --help and of the daemon as one types). bash and fish load a completion by the name of
# the command: one file per program; zsh's names the four programs in its #compdef line.
if(ZEROCAL_INSTALL_EXTRAS)
  foreach(program zerocal zerocal-lab zerocald zerocal-sim)
    install(FILES config/bash-completion/zerocal
            DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions RENAME ${program})
    install(FILES config/fish/zerocal.fish
            DESTINATION ${CMAKE_INSTALL_DATADIR}/fish/vendor_completions.d RENAME ${program}.fish)
  endforeach()
  install(FILES config/zsh/_zerocal DESTINATION ${CMAKE_INSTALL_DATADIR}/zsh/vendor-completions)
endif()

# The man pages, written as roff in man/ (tests/install/man_pages_test.sh keeps them to --help).
if(ZEROCAL_INSTALL_EXTRAS)
  install(FILES man/zerocal.1 man/zerocal-lab.1 man/zerocal-sim.1
          DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
  install(FILES man/zerocald.8 DESTINATION ${CMAKE_INSTALL_MANDIR}/man8)
endif()
