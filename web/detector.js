// The spot on the PSD, drawn in the detector's own millimetres (u right, v up; the SVG's y points
// down, hence the minus). Off the detector, or no reading: the spot is hidden.
export function drawSpot(svg, reading) {
  const spot = svg.querySelector("#spot");
  if (!reading || !reading.spot_present) {
    spot.setAttribute("visibility", "hidden");
    return;
  }
  const clamp = (x) => Math.max(-6.8, Math.min(6.8, x));
  spot.setAttribute("cx", clamp(reading.u_mm).toFixed(3));
  spot.setAttribute("cy", clamp(-reading.v_mm).toFixed(3));
  spot.setAttribute("visibility", "visible");
}
