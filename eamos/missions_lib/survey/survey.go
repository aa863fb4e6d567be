// Package survey: a lawnmower survey over a rectangle.
//
//	import "survey"
//	survey.SEQ_Lawnmower(D1, 0, 0, 20, 12, 4)
package survey

import "fleet"

// SEQ_Lawnmower sweeps the rectangle from corner (x_m, y_m), length_m north
// and width_m east, at height z_m, in four passes along X spaced width_m/3
// apart.  It ends at the corner (x_m, y_m + width_m).
func SEQ_Lawnmower(d fleet.Flyer, x_m float64, y_m float64, length_m float64, width_m float64, z_m float64) {
	d.FlyToXYZ(x_m, y_m, z_m)
	d.FlyToXYZ(x_m+length_m, y_m, z_m)
	d.FlyToXYZ(x_m+length_m, y_m+width_m/3, z_m)
	d.FlyToXYZ(x_m, y_m+width_m/3, z_m)
	d.FlyToXYZ(x_m, y_m+2*width_m/3, z_m)
	d.FlyToXYZ(x_m+length_m, y_m+2*width_m/3, z_m)
	d.FlyToXYZ(x_m+length_m, y_m+width_m, z_m)
	d.FlyToXYZ(x_m, y_m+width_m, z_m)
}

// SEQ_Sweep sweeps from where the drone is, at its height: `pairs` times
// length_m north, spacing_m east, length_m south, spacing_m east.  It ends
// 2 * pairs * spacing_m east of where it started.
func SEQ_Sweep(d fleet.Flyer, length_m float64, spacing_m float64, pairs float64) {
	RepeatFor(pairs, SEQ_TwoLegs(d, length_m, spacing_m))
}

// SEQ_TwoLegs is one pair of legs of SEQ_Sweep.
func SEQ_TwoLegs(d fleet.Flyer, length_m float64, spacing_m float64) {
	d.FlyByX(length_m)
	d.FlyByY(spacing_m)
	d.FlyByX(-length_m)
	d.FlyByY(spacing_m)
}
