# The Debian package: `cpack -G DEB` in a build folder configured with -DCMAKE_INSTALL_PREFIX=/usr
# (docs/daemon.md). The package holds what `cmake --install` installs, at the same paths, so the
# unit inside it runs the zerocald inside it. Every file shipped under the configuration folder is
# a conffile: an upgrade keeps a technician's edits (dpkg asks).
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME zerocal)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "joint zero-offset calibration of industrial robots")
set(CPACK_PACKAGE_DESCRIPTION
    "zerocald drives an ABB IRC5 robot through planned poses, servoes a flange laser onto a PSD "
    "read through a USB-1408FS, and identifies the joint zero offsets with their uncertainty; "
    "zerocal is the technician's terminal client, zerocal-lab the engine's command line.")
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "zerocal developers <zerocal@localhost>")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
# The shared libraries' packages (libceres3, libusb-1.0-0, ...) from the binaries themselves;
# systemd for sysusers, the unit and the credentials.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "systemd (>= 250)")
set(CPACK_STRIP_FILES ON)
set(CPACK_PACKAGING_INSTALL_PREFIX ${CMAKE_INSTALL_PREFIX})
# Absolute destinations (/etc/zerocal, the unit and udev folders) go into the package, not onto
# the machine that builds it.
set(CPACK_SET_DESTDIR ON)

set(_zerocal_pkg ${PROJECT_BINARY_DIR}/packaging)
file(GLOB _zerocal_conf RELATIVE ${PROJECT_SOURCE_DIR}/config ${PROJECT_SOURCE_DIR}/config/robots/*
     ${PROJECT_SOURCE_DIR}/config/worlds/*)
set(_zerocal_conffiles "")
foreach(f zerocald.yaml psd.yaml psd-map.yaml ${_zerocal_conf})
  string(APPEND _zerocal_conffiles "${ZEROCAL_CONFDIR}/${f}\n")
endforeach()
# Outside the prefix /usr the unit, the rule and the sysusers file are in /etc too: conffiles.
foreach(dir_file "${ZEROCAL_SYSTEMD_UNITDIR}/zerocald.service"
        "${ZEROCAL_UDEV_RULESDIR}/60-zerocal-usb1408fs.rules" "${ZEROCAL_SYSUSERSDIR}/zerocal.conf")
  if(dir_file MATCHES "^/etc/")
    string(APPEND _zerocal_conffiles "${dir_file}\n")
  endif()
endforeach()
file(WRITE ${_zerocal_pkg}/conffiles ${_zerocal_conffiles})
foreach(script postinst prerm postrm)
  configure_file(${PROJECT_SOURCE_DIR}/packaging/debian/${script}.in ${_zerocal_pkg}/${script} @ONLY
                 FILE_PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE
                 WORLD_READ WORLD_EXECUTE)
endforeach()
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA ${_zerocal_pkg}/conffiles ${_zerocal_pkg}/postinst
    ${_zerocal_pkg}/prerm ${_zerocal_pkg}/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION TRUE)
include(CPack)
