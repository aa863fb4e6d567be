// One drone flies a long leg (tests/operator/test_pause_sitl.py): the operator pauses it
// mid-leg on a real autopilot; on resume it goes on to the leg's original end.
package LongLeg

var Drone1 Quadcopter

func SEQ_Mission() {
	Drone1.Arm()
	Drone1.Takeoff(2)
	Drone1.FlyByX(40)
	Drone1.Land()
}
