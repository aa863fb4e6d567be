// Two drones whose legs cross: Drone2 flies 40 m north along a line Drone1 later
// flies 20 m east across.  At the speeds their type declares Drone2 is long past the
// crossing when Drone1 reaches it; a Drone2 slowed down (wind, a weak motor) is not.
// The fleet that places them: configs/crossing.toml (configs/crossing_slow.toml slows
// Drone2 down and turns the live look-ahead on).
package crossing

import "fleet"

func SEQ_Crossing() {
	fleet.PAR_TakeOff2(Drone1, Drone2, 3)
	PAR_Legs()
	fleet.PAR_Land2(Drone1, Drone2)
}

func PAR_Legs() {
	SEQ_Leg1()
	SEQ_Leg2()
}

func SEQ_Leg1() {
	Drone1.PauseFor(15)
	Drone1.FlyByY(20)
}

func SEQ_Leg2() {
	Drone2.FlyByX(40)
}
