// Two drones whose legs cross: Drone2 flies 40 m north along a line Drone1 later
// flies 20 m east across.  At the speeds their type declares Drone2 is long past the
// crossing when Drone1 reaches it; a Drone2 slowed down (wind, a weak motor) is not.
// The fleet that places them: configs/crossing.toml.
package main

func SEQ_Crossing() {
	PAR_Up()
	PAR_Legs()
	PAR_Down()
}

func PAR_Up() {
	SEQ_Up1()
	SEQ_Up2()
}

func SEQ_Up1() {
	Drone1.Arm()
	Drone1.Takeoff(3)
}

func SEQ_Up2() {
	Drone2.Arm()
	Drone2.Takeoff(3)
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

func PAR_Down() {
	SEQ_Down1()
	SEQ_Down2()
}

func SEQ_Down1() {
	Drone1.Land()
	Drone1.Disarm()
}

func SEQ_Down2() {
	Drone2.Land()
	Drone2.Disarm()
}
