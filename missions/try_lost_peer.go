// A Try catches a lost peer: Drone2's part of the relay waits for Drone1; when
// Drone1's link is lost for longer than peer_wait_limit_s, the wait fails inside
// the Try's Body, which the Try catches: Drone2 flies OnFailure (back home)
// instead of applying its end policy where it is.  (The Try's end is hosted by
// the drone that starts Body, Drone2 here: a Try whose end lives on the lost
// drone cannot run OnFailure, and the waiting drone applies its end policy.)
package TryLostPeer

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Mission() {
	PAR_Up()
	Try(SEQ_Relay, SEQ_Back)
	PAR_Down()
}

func PAR_Up() {
	SEQ_Up1()
	SEQ_Up2()
}

func SEQ_Up1() {
	Drone1.Arm()
	Drone1.Takeoff(2)
}

func SEQ_Up2() {
	Drone2.Arm()
	Drone2.Takeoff(2)
}

func SEQ_Relay() {
	Drone2.FlyByX(3)
	Drone1.FlyByX(20)
	Drone2.FlyByY(2)
}

func SEQ_Back() {
	Drone2.FlyToXYZ(0, 0, 2)
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
