// Package fleet: take-off-all and land-all for two to four drones, and the Flyer type.
//
//	import "fleet"
//	fleet.PAR_TakeOff2(D1, D2, 2.5)
//	fleet.PAR_Land2(D1, D2)
package fleet

// Flyer is any drone that flies with the uniform API's flight actions: every
// drone type of the uniform API satisfies it (DroneType1 to 3 included).
type Flyer interface {
	Arm()
	Disarm()
	Takeoff(height_m float64)
	Land()
	FlyByX(distance_m float64)
	FlyByY(distance_m float64)
	FlyByZ(distance_m float64)
	FlyToXYZ(x_m, y_m, z_m float64)
	PauseFor(duration_s float64)
}

// SEQ_Up arms one drone and climbs to height_m above its home.
func SEQ_Up(d Flyer, height_m float64) {
	d.Arm()
	d.Takeoff(height_m)
}

// SEQ_Down lands one drone where it is.
func SEQ_Down(d Flyer) {
	d.Land()
}

func PAR_TakeOff2(a Flyer, b Flyer, height_m float64) {
	SEQ_Up(a, height_m)
	SEQ_Up(b, height_m)
}

func PAR_TakeOff3(a Flyer, b Flyer, c Flyer, height_m float64) {
	SEQ_Up(a, height_m)
	SEQ_Up(b, height_m)
	SEQ_Up(c, height_m)
}

func PAR_TakeOff4(a Flyer, b Flyer, c Flyer, e Flyer, height_m float64) {
	SEQ_Up(a, height_m)
	SEQ_Up(b, height_m)
	SEQ_Up(c, height_m)
	SEQ_Up(e, height_m)
}

func PAR_Land2(a Flyer, b Flyer) {
	SEQ_Down(a)
	SEQ_Down(b)
}

func PAR_Land3(a Flyer, b Flyer, c Flyer) {
	SEQ_Down(a)
	SEQ_Down(b)
	SEQ_Down(c)
}

func PAR_Land4(a Flyer, b Flyer, c Flyer, e Flyer) {
	SEQ_Down(a)
	SEQ_Down(b)
	SEQ_Down(c)
	SEQ_Down(e)
}
