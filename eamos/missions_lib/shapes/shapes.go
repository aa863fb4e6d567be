// Package shapes: a square and an orbit around a point, flown by one drone.
//
//	import "shapes"
//	shapes.SEQ_Square(D1, 5)
//	shapes.SEQ_Orbit(D1, 10, 0, 4, 3)
package shapes

import "fleet"

// SEQ_Square flies a square of side side_m: north, east, south, west, back
// where it started.
func SEQ_Square(d fleet.Flyer, side_m float64) {
	d.FlyByX(side_m)
	d.FlyByY(side_m)
	d.FlyByX(-side_m)
	d.FlyByY(-side_m)
}

// SEQ_Orbit flies once around the point (x_m, y_m) at height z_m, radius
// radius_m, as an octagon: it starts and ends on the point's north side,
// (x_m + radius_m, y_m, z_m), and turns clockwise seen from above.
func SEQ_Orbit(d fleet.Flyer, x_m float64, y_m float64, radius_m float64, z_m float64) {
	d.FlyToXYZ(x_m+radius_m, y_m, z_m)
	d.FlyToXYZ(x_m+radius_m*0.7071067811865476, y_m+radius_m*0.7071067811865476, z_m)
	d.FlyToXYZ(x_m, y_m+radius_m, z_m)
	d.FlyToXYZ(x_m-radius_m*0.7071067811865476, y_m+radius_m*0.7071067811865476, z_m)
	d.FlyToXYZ(x_m-radius_m, y_m, z_m)
	d.FlyToXYZ(x_m-radius_m*0.7071067811865476, y_m-radius_m*0.7071067811865476, z_m)
	d.FlyToXYZ(x_m, y_m-radius_m, z_m)
	d.FlyToXYZ(x_m+radius_m*0.7071067811865476, y_m-radius_m*0.7071067811865476, z_m)
	d.FlyToXYZ(x_m+radius_m, y_m, z_m)
}
