// Package fleet: take off and land a group of drones, at once or one after the other,
// and the Flyer type.
//
//	import "fleet"
//	var Team [10]Quadcopter
//	fleet.PAR_TakeOff(Team, 2.5)     // every member at once
//	fleet.SEQ_Land(Team[0:5])        // the first five, one after the other
//
// PAR_TakeOff2/3/4 and PAR_Land2/3/4 take two to four drones by name (before groups).
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

// SEQ_Park lands one drone where it is and disarms it.
func SEQ_Park(d Flyer) {
	d.Land()
	d.Disarm()
}

// PAR_TakeOff arms every drone of the group and climbs it to height_m, all at once.
func PAR_TakeOff(g []Flyer, height_m float64) {
	for _, d := range g {
		SEQ_Up(d, height_m)
	}
}

// SEQ_TakeOff arms and climbs the drones of the group one after the other (a relay).
func SEQ_TakeOff(g []Flyer, height_m float64) {
	for _, d := range g {
		SEQ_Up(d, height_m)
	}
}

// PAR_Land lands every drone of the group where it is and disarms it, all at once.
func PAR_Land(g []Flyer) {
	for _, d := range g {
		SEQ_Park(d)
	}
}

// SEQ_Land lands and disarms the drones of the group one after the other.
func SEQ_Land(g []Flyer) {
	for _, d := range g {
		SEQ_Park(d)
	}
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
